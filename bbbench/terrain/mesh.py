"""Heightmaps as triangle meshes: for inspection (.obj, .stl) and for bullet's mesh shapes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from bbbench.files import write_atomic
from bbbench.terrain.heightmap import Heightmap

EXPORT_FORMATS = (".obj", ".stl", ".ply", ".glb")


def vertices_and_faces(heightmap: Heightmap) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (N, 3) and triangles (M, 3): two per cell, counter-clockwise seen from above."""
    nx, ny = heightmap.shape
    xs, ys = heightmap.node_coordinates()
    grid_x, grid_y = np.meshgrid(xs, ys, indexing="ij")
    vertices = np.column_stack([grid_x.ravel(), grid_y.ravel(), heightmap.heights.ravel()])
    index = np.arange(nx * ny).reshape(nx, ny)
    a, b = index[:-1, :-1].ravel(), index[1:, :-1].ravel()  # nodes (i, j), (i+1, j)
    c, d = index[1:, 1:].ravel(), index[:-1, 1:].ravel()  # nodes (i+1, j+1), (i, j+1)
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return vertices, faces


def to_trimesh(heightmap: Heightmap) -> trimesh.Trimesh:
    """The heightmap's surface as a mesh, normals up."""
    vertices, faces = vertices_and_faces(heightmap)
    return trimesh.Trimesh(vertices=vertices, faces=faces, process=False)


def export(heightmap: Heightmap, path: str | Path) -> Path:
    """Write the heightmap as a mesh file (.obj, .stl, .ply or .glb), atomically."""
    path = Path(path)
    if path.suffix.lower() not in EXPORT_FORMATS:
        raise ValueError(
            f"cannot write a terrain as {path.name!r}: expected a file name ending in "
            f"{', '.join(EXPORT_FORMATS)}"
        )
    data = to_trimesh(heightmap).export(file_type=path.suffix.lower()[1:])
    return write_atomic(path, data if isinstance(data, bytes) else data.encode())

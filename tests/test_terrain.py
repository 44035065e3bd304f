"""Terrain: seeded generators within their bounds, meshes and bullet heightfields that match."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
import trimesh

from bbbench.portable import exp as exp_same_everywhere
from bbbench.sim import World
from bbbench.terrain.bullet import BulletHeightfield, HeightfieldBody
from bbbench.terrain.generators import GENERATORS, Bumps
from bbbench.terrain.heightmap import HeightfieldTerrain
from bbbench.terrain.mesh import export, to_trimesh

GENERATOR_NAMES = sorted(GENERATORS)


def terrain(name: str, difficulty: float = 0.5) -> HeightfieldTerrain:
    return HeightfieldTerrain(generator=GENERATORS[name](), difficulty=difficulty)


@pytest.mark.parametrize("name", GENERATOR_NAMES)
def test_generators_are_deterministic_per_seed(name):
    first = terrain(name).generate(np.random.default_rng(3)).heights
    again = terrain(name).generate(np.random.default_rng(3)).heights
    assert np.array_equal(first, again)
    if name != "flat":
        other = terrain(name).generate(np.random.default_rng(4)).heights
        assert not np.array_equal(first, other)


@pytest.mark.parametrize("name", GENERATOR_NAMES)
@pytest.mark.parametrize("difficulty", [0.0, 0.5, 1.0])
def test_heights_stay_within_the_stated_bounds(name, difficulty):
    spec = terrain(name, difficulty)
    low, high = spec.height_bounds
    for seed in range(5):
        heights = spec.generate(np.random.default_rng(seed)).heights
        assert heights.min() >= low
        assert heights.max() <= high + 1e-12


def test_bumps_are_a_fraction_of_the_wheel_radius_at_low_difficulty():
    assert Bumps().max_height(0.0) <= 0.5 * 0.1
    assert Bumps().max_height(1.0) > Bumps().max_height(0.0)


@pytest.mark.parametrize("bad", [-0.1, 1.5, float("nan")])
def test_difficulty_outside_0_1_is_refused(bad):
    with pytest.raises(ValueError, match=r"difficulty must be a number in \[0, 1\]"):
        HeightfieldTerrain(generator=Bumps(), difficulty=bad)


def test_the_start_pad_is_level():
    heightmap = terrain("bumps", 1.0).generate(np.random.default_rng(0))
    xs, ys = heightmap.node_coordinates()
    pad = np.hypot(xs[:, None], ys[None, :]) <= 0.5
    assert np.ptp(heightmap.heights[pad]) < 1e-12


@pytest.mark.parametrize("name", GENERATOR_NAMES)
def test_the_strip_fades_to_flat_ground_at_its_edges(name):
    heightmap = terrain(name, 1.0).generate(np.random.default_rng(3))
    edges = np.concatenate(
        [
            heightmap.heights[0],
            heightmap.heights[-1],
            heightmap.heights[:, 0],
            heightmap.heights[:, -1],
        ]
    )
    assert np.all(edges == 0.0)


def test_flat_ground_surrounds_the_strip():
    """Past every edge a ray meets flat ground at z = 0, not a drop."""
    spec = terrain("bumps", 1.0)
    world = World(time_step=0.01)
    ground = BulletHeightfield(world.client, spec)
    ground.reset(np.random.default_rng(0))
    x_min, x_max, y_min, y_max = spec.bounds
    outside = [
        (x_min - 1, 0),
        (x_max + 1, 0),
        (0, y_min - 1),
        (0, y_max + 1),
        (x_max + 20, y_max + 20),
    ]
    hits = world.client.rayTestBatch(
        [(x, y, 5.0) for x, y in outside], [(x, y, -5.0) for x, y in outside]
    )
    assert all(hit[0] in ground.surround for hit in hits)
    assert [hit[3][2] for hit in hits] == pytest.approx([0.0] * len(outside), abs=1e-9)
    world.close()


def test_mesh_has_two_upward_triangles_per_cell():
    heightmap = terrain("obstacles").generate(np.random.default_rng(1))
    mesh = to_trimesh(heightmap)
    nx, ny = heightmap.shape
    assert len(mesh.faces) == 2 * (nx - 1) * (ny - 1)
    assert np.all(mesh.face_normals[:, 2] > 0)


@pytest.mark.parametrize("name", ["bumps", "obstacles", "slopes"])
def test_heightmap_mesh_and_bullet_heightfield_agree(name):
    """Round trip: heightmap -> mesh vertices -> raycasts on the bullet heightfield."""
    spec = terrain(name, 0.8)
    world = World(time_step=0.01)
    field = HeightfieldBody(world.client, spec.grid_shape, spec.cell_size, spec.height_bounds)
    for seed in (0, 1):  # the second terrain replaces the first in place
        heightmap = spec.generate(np.random.default_rng(seed))
        field.show(heightmap)
        vertices = to_trimesh(heightmap).vertices
        # Interior nodes: rays exactly on the field's outer edge can miss it.
        nx, ny = heightmap.shape
        index = np.arange(nx * ny).reshape(nx, ny)[1:-1, 1:-1].ravel()
        sample = np.random.default_rng(9).choice(index, size=400, replace=False)
        x, y, z = vertices[sample].T
        hits = world.client.rayTestBatch(
            np.column_stack([x, y, np.full_like(x, 5.0)]).tolist(),
            np.column_stack([x, y, np.full_like(x, -5.0)]).tolist(),
        )
        assert all(hit[0] == field.body for hit in hits)
        assert np.array([hit[3][2] for hit in hits]) == pytest.approx(z, abs=1e-6)
    world.close()


def test_export_writes_a_mesh_file_atomically(tmp_path):
    heightmap = terrain("bumps").generate(np.random.default_rng(0))
    path = export(heightmap, tmp_path / "terrain.obj")
    loaded = trimesh.load(path, process=False)
    assert len(loaded.vertices) == heightmap.heights.size
    assert [p.name for p in tmp_path.iterdir()] == ["terrain.obj"]  # no partial file left
    with pytest.raises(ValueError, match=r"expected a file name ending in \.obj"):
        export(heightmap, tmp_path / "terrain.txt")


# The bits of an eval seed's terrain, as generated on the machine that built the
# leaderboard (AVX-512). Any machine must give the same: the leaderboard check
# compares episodes played on it byte for byte.
TERRAIN_BITS = {
    "bbbench/Bumps-v1": "a74cd920fa4b0e621f954805bc1cfeed3a006a9385a723d7c8363d666a94a56e",
    "bbbench/Bumps-v0": "9fb45e79b81d1a4f4b43728c3f4bcc6accbcb5575ae452a33ec68d45ac560970",
}
TERRAIN_HASH = """
import hashlib, sys
import bbbench
from bbbench.tasks.spec import seed_streams
task = bbbench.spec(sys.argv[1])
heights = task.terrain.generate(seed_streams(task.eval_seeds[0]).terrain).heights
print(hashlib.sha256(heights.tobytes()).hexdigest())
"""


@pytest.mark.parametrize("task_id", sorted(TERRAIN_BITS))
def test_terrain_has_the_same_bits_on_every_cpu(task_id):
    """numpy's exp rounds differently on AVX-512 and AVX2 CPUs; terrain must not."""
    for disabled in ("", "X86_V4 AVX512_ICL"):  # this CPU's SIMD paths, then AVX2's
        env = {**os.environ, "NPY_DISABLE_CPU_FEATURES": disabled}
        run = subprocess.run(
            [sys.executable, "-c", TERRAIN_HASH, task_id], env=env, capture_output=True, text=True
        )
        if disabled and run.returncode and "NPY_DISABLE_CPU_FEATURES" in run.stderr:
            continue  # a CPU without AVX-512: its own paths were checked above
        assert run.returncode == 0, run.stderr
        assert run.stdout.strip() == TERRAIN_BITS[task_id]


def test_exp_same_everywhere_is_exp_to_the_last_bit():
    x = np.concatenate([np.linspace(-800.0, 0.0, 20001), np.linspace(-1.0, 1.0, 2001)])
    ours, numpys = exp_same_everywhere(x), np.exp(x)
    assert np.all(np.abs(ours - numpys) <= np.spacing(numpys))
    assert exp_same_everywhere(np.array([0.0]))[0] == 1.0

"""`bbbench terrain`: the ground of a task's episode, as a mesh file."""

from __future__ import annotations

import argparse

import bbbench
from bbbench.cli.common import UsageError, check_seed
from bbbench.files import check_output_path
from bbbench.tasks.spec import seed_streams
from bbbench.terrain import HeightfieldTerrain


def add_parser(commands) -> None:
    terrain = commands.add_parser(
        "terrain", help="write the terrain of a task's episode seed as a mesh (.obj, .stl, ...)"
    )
    terrain.add_argument("--task", default="bbbench/Bumps-v0", help="a task with terrain")
    terrain.add_argument("--seed", type=int, default=0, help="episode seed (default 0)")
    terrain.add_argument("--difficulty", type=float, help="in [0, 1]; default: the task's")
    terrain.add_argument("--out", required=True, help="output file: .obj, .stl, .ply or .glb")
    terrain.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    try:
        spec = bbbench.spec(args.task)
        if args.difficulty is not None:
            spec = spec.with_difficulty(args.difficulty)
    except (ValueError, TypeError) as error:
        raise UsageError(str(error)) from None
    if not isinstance(spec.terrain, HeightfieldTerrain):
        terrain_tasks = [t for t in bbbench.list_tasks() if bbbench.spec(t).difficulty is not None]
        raise UsageError(
            f"{spec.id} is on flat ground: there is no terrain to write. Tasks with terrain: "
            f"{', '.join(terrain_tasks)}"
        )
    try:  # where it goes, before the terrain is made: no temporary name in an error
        check_output_path(args.out, "--out")
    except ValueError as error:
        raise UsageError(str(error)) from None
    from bbbench.terrain.mesh import export  # lazy: trimesh, for this command only

    heightmap = spec.terrain.generate(seed_streams(check_seed(args.seed)).terrain)
    try:
        path = export(heightmap, args.out)
    except (ValueError, OSError) as error:
        raise UsageError(str(error)) from None
    low, high = float(heightmap.heights.min()), float(heightmap.heights.max())
    print(
        f"wrote {path}: {spec.id} (difficulty {spec.difficulty:g}), episode seed {args.seed}, "
        f"{heightmap.extent[0]:g} x {heightmap.extent[1]:g} m, heights {low:.3f}..{high:.3f} m"
    )

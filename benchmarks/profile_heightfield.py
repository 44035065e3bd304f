"""Where a terrain reset's heightfield upload goes: replace Bumps-v0's heights, many times.

    perf record -g -o /tmp/perf.data python benchmarks/profile_heightfield.py
    perf report -i /tmp/perf.data --no-children --sort symbol

Each round draws the next episode's terrain once (outside the timed part), then
times `HeightfieldBody.show` alone, the one pybullet call that replaces the
heights in place (`createCollisionShape(..., replaceHeightfieldIndex=...)`), and
prints its mean. Under `perf` the report names the pybullet functions that take
the time (docs/performance.md, "Terrain resets").
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym

import bbbench  # noqa: F401 (registers the tasks)
from bbbench.tasks.spec import seed_streams


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="bbbench/Bumps-v0")
    parser.add_argument("--uploads", type=int, default=3000)
    args = parser.parse_args()
    env = gym.make(args.task)
    env.reset(seed=0)
    ground = env.unwrapped.scene.ground
    heightmaps = [ground.terrain.generate(seed_streams(seed).terrain) for seed in range(50)]
    took = 0.0
    for k in range(args.uploads):
        heightmap = heightmaps[k % len(heightmaps)]
        began = time.perf_counter()
        ground.field.show(heightmap)
        took += time.perf_counter() - began
    grid = "x".join(map(str, ground.field.grid_shape))
    print(f"{args.task}: {grid} heights replaced in {took / args.uploads * 1e3:.3f} ms on average")
    env.close()


if __name__ == "__main__":
    main()

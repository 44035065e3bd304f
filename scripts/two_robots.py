"""The two robots on the same ground: the wheel-legged robot under its classical controller
and the two-wheel bot under PD (its discrete baseline), each on every task of either
robot's single-bot terrain, with the same ground, seeds and targets (each task's spec with
the other robot, `dataclasses.replace(spec(task_id), robot=...)`, played through
`BalanceEnv`), on the 100 evaluation seeds.

    python scripts/two_robots.py --evaluate   # writes baselines/calibrations/two-robots.json
    python scripts/two_robots.py --table      # docs/tasks.md's block

The record keeps every episode's return and whether it finished; docs/tasks.md's table is
printed from it (tests/test_calibrations.py replays some episodes).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
RECORD = ROOT / "baselines" / "calibrations" / "two-robots.json"
TASKS = {  # task -> what its ground is, as the table says
    "bbbench/FlatBalance-v1": "",
    "bbbench/VelocityTracking-v1": "",
    "bbbench/Bumps-v2": "hills up to {height:g} m",
    "bbbench/Obstacles-v2": "obstacles up to {height:g} m",
    "bbbench/LeggedBumps-v0": "hills up to {height:g} m",
    "bbbench/LeggedObstacles-v0": "obstacles up to {height:g} m",
}
ROBOTS = {"wheel-legged": "wheel-legged, classical", "two-wheel": "two-wheel, PD"}


def player(robot: str, task_id: str):
    """The robot's classical controller (`Robot.controller`) on the task, as the
    evaluation harness plays it, and its action mode."""
    from bbbench.policies import load_policy
    from bbbench.robots import ROBOTS as MODELS

    policy = load_policy(MODELS[robot].controller)
    return policy.actor(task_id), policy.action_mode


def variant(task_id: str, robot: str):
    """The task's spec with `robot` playing it."""
    from bbbench.tasks.suite import spec

    return dataclasses.replace(spec(task_id), robot=robot)


def play(task_id: str, robot: str, seeds: Sequence[int]) -> list[dict[str, Any]]:
    """The robot's episodes of the task's ground, seeds and targets."""
    from bbbench.evaluation.episodes import LockstepPlayer
    from bbbench.evaluation.harness import LOCKSTEP

    actor, mode = player(robot, task_id)
    runner = LockstepPlayer(actors={task_id: actor}, action_mode=mode, sampled=False)
    task, episodes = variant(task_id, robot), []
    try:  # in the harness's groups of seeds (an episode depends on its seed alone)
        for start in range(0, len(seeds), LOCKSTEP):
            episodes += runner.play(task, list(seeds[start : start + LOCKSTEP]))
    finally:
        runner.close()
    return [{"return": e.episode_return, "finished": e.success} for e in episodes]


def evaluate() -> dict[str, Any]:
    from bbbench.evaluation import machine
    from bbbench.tasks.suite import spec

    start = time.monotonic()
    rows = {}
    for task_id in TASKS:
        seeds = spec(task_id).eval_seeds
        rows[task_id] = {robot: play(task_id, robot, seeds) for robot in ROBOTS}
        print(f"{task_id}: {time.monotonic() - start:.0f} s", file=sys.stderr)
    return {
        "schema": "bbbench-two-robots/1",
        "tasks": rows,
        "split": "evaluation",
        "seeds": {"first": spec(next(iter(TASKS))).eval_seeds[0], "count": 100},
        "command": "python scripts/two_robots.py --evaluate",
        "seconds": round(time.monotonic() - start, 1),
        "machine": machine.described(machine.record()),
        "date": time.strftime("%Y-%m-%d"),
    }


def table(record: dict[str, Any]) -> str:
    from bbbench.portable import total
    from bbbench.tasks.suite import spec

    lines = [
        "| task (ground, seeds, targets) | " + " | ".join(ROBOTS.values()) + " |",
        "|---|" + "---|" * len(ROBOTS),
    ]
    for task_id, ground in TASKS.items():
        terrain = spec(task_id).terrain
        if ground:
            generator, difficulty = terrain.generator, terrain.difficulty
            ground = (
                " (" + ground.format(height=round(generator.height_bounds(difficulty)[1], 3)) + ")"
            )
        cells = []
        for robot in ROBOTS:
            episodes = record["tasks"][task_id][robot]
            finished = sum(episode["finished"] for episode in episodes)
            mean = total(episode["return"] for episode in episodes) / len(episodes)
            cells.append(f"{finished}, {mean:.1f}")
        lines.append(f"| {task_id.removeprefix('bbbench/')}{ground} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--evaluate", action="store_true", help="play and write the record")
    parser.add_argument("--table", action="store_true", help="print docs/tasks.md's block")
    args = parser.parse_args(argv)
    if args.evaluate:
        RECORD.parent.mkdir(parents=True, exist_ok=True)
        partial = RECORD.with_suffix(".json.partial")
        partial.write_text(json.dumps(evaluate(), indent=1) + "\n")
        partial.replace(RECORD)
    if args.table:
        print(table(json.loads(RECORD.read_text())))
    return 0


if __name__ == "__main__":
    sys.exit(main())

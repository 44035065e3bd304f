"""docs/tasks.md's tables that quote the board: printed from `leaderboards/bbbench-v0.json`
and the runs' results documents in `leaderboards/results/` (the classical controllers'
episodes on the 100 evaluation seeds), so that no figure in them is typed by hand.

    python scripts/board_tables.py --every-task   # every task on the shared reward
    python scripts/board_tables.py --steering     # the steering tasks' calibration
    python scripts/board_tables.py --swap         # Swap-v0's two controllers
    python scripts/board_tables.py --convoyturns  # ConvoyTurns-v0's team controller

scripts/check_docs.py runs each and compares its output with the block in the page.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bbbench.evaluation.results import read

sys.path.insert(0, str(Path(__file__).parent))
from board_runs import short

ROOT = Path(__file__).resolve().parents[1]
BOARD = ROOT / "leaderboards" / "bbbench-v0.json"
RESULTS = ROOT / "leaderboards" / "results"
REWARD_TASKS = (
    "bbbench/Bumps-v2",
    "bbbench/FlatBalance-v1",
    "bbbench/NoisySensors-v1",
    "bbbench/Obstacles-v2",
    "bbbench/Slopes-v2",
    "bbbench/VelocityTracking-v1",
    "bbbench/MultiBalance-v1",
    "bbbench/MultiBumps-v1",
    "bbbench/MultiNoisySensors-v0",
)
STEERING_TASKS = ("bbbench/SteerTracking-v0", "bbbench/Waypoints-v1", "bbbench/WaypointsBumps-v1")


def board_methods() -> list[dict[str, Any]]:
    board = json.loads(BOARD.read_text())
    return [method for track in board["tracks"] for method in track["methods"]]


def controller(slug: str, task_id: str) -> dict[str, Any]:
    """A built-in controller's block for a task in its results document (its one run)."""
    document = read(RESULTS / f"{slug}.json")
    (block,) = [block for block in document["tasks"] if block["task"] == task_id]
    return block


def returns(block: dict[str, Any]) -> np.ndarray:
    return np.array([episode["return"] for episode in block["episodes"]])


def every_task() -> str:
    """Each task's row: random's mean return, stand, PD and LQR normalized, and the best
    learned method on it (its mean over runs), whichever task it trained on."""
    import bbbench

    methods = board_methods()
    lines = [
        "| task | random (mean return) | stand | PD | LQR | best learned method (mean over its "
        "runs) |",
        "|---|---:|---:|---:|---:|---|",
    ]
    for task_id in REWARD_TASKS:
        scores = {
            method["slug"]: (method["tasks"][task_id]["normalized_score"], method["submission"])
            for method in methods
            if task_id in method["tasks"]
        }
        learned = [
            (score, submission["name"])
            for score, submission in scores.values()
            if "builtin" not in submission
        ]
        best, name = max(learned, key=lambda pair: pair[0])
        builtins = " | ".join(f"{scores[slug][0]:.3f}" for slug in ("stand", "pd", "lqr"))
        lines.append(
            f"| {short(task_id)} | 0 ({bbbench.spec(task_id).random_return:.2f}) "
            f"| {builtins} | {best:.3f} ({name}) |"
        )
    return "\n".join(lines)


def steering() -> str:
    """The steering law on the steering robot's single-bot tasks' evaluation seeds."""
    import bbbench

    lines = ["| task | finished | mean return | normalized |", "|---|---|---|---|"]
    for task_id in STEERING_TASKS:
        aggregate = controller("steer", task_id)["aggregate"]
        difficulty = bbbench.spec(task_id).difficulty
        name = short(task_id) + (f" (difficulty {difficulty:g})" if "Bumps" in task_id else "")
        finished = round(aggregate["success_rate"] * aggregate["episodes"])
        lines.append(
            f"| {name} | {finished} / {aggregate['episodes']} | {aggregate['mean']:.1f} | "
            f"{aggregate['normalized_score']:.3f} |"
        )
    return "\n".join(lines)


def swap() -> str:
    """Swap-v0's controllers on the evaluation seeds, and P(steer-avoid > steer)."""
    from bbbench.evaluation.stats import probability_of_improvement

    task_id = "bbbench/Swap-v0"
    lines = [
        "| controller | whole episodes (no bot fell) | falls | mean return per bot | normalized |",
        "|---|---|---|---|---|",
    ]
    blocks = {slug: controller(slug, task_id) for slug in ("steer", "steer-avoid", "random")}
    for slug, block in blocks.items():
        aggregate = block["aggregate"]
        whole = round(aggregate["success_rate"] * aggregate["episodes"])
        falls = sum(episode["falls"] for episode in block["episodes"])
        name = "random" if slug == "random" else f"`{slug}`"
        lines.append(
            f"| {name} | {whole} / {aggregate['episodes']} | {falls} | {aggregate['mean']:.2f} | "
            f"{aggregate['normalized_score']:.3f} |"
        )
    point, (low, high) = probability_of_improvement(
        [returns(blocks["steer-avoid"])], [returns(blocks["steer"])]
    )
    lines += [
        "",
        f"P(`steer-avoid` > `steer`) = {point:.3f} [{low:.3f}, {high:.3f}] (rliable's "
        "probability of improvement over the episodes' returns).",
    ]
    return "\n".join(lines)


def convoyturns() -> str:
    """ConvoyTurns-v0's team controller on the evaluation seeds, in a sentence."""
    team = controller("team", "bbbench/ConvoyTurns-v0")
    random = controller("random", "bbbench/ConvoyTurns-v0")["aggregate"]
    causes = [episode["cause"] for episode in team["episodes"]]
    whole = causes.count("time limit")
    fell = sum("fell" in cause for cause in causes)
    broke = len(causes) - whole - fell
    aggregate = team["aggregate"]
    finished = "none" if random["success_rate"] == 0 else f"{random['success_rate']:.0%}"
    return (
        f"On the {aggregate['episodes']} evaluation seeds (discrete actions), `team` keeps the "
        f"column whole to the time limit in {whole} episodes (of the other "
        f"{len(causes) - whole}, {fell} end with a fall and {broke} with a broken tether), "
        f"mean return {aggregate['mean']:.1f}, {aggregate['normalized_score']:.3f} "
        f"normalized; random finishes {finished}."
    )


TABLES = {
    "every-task": every_task,
    "steering": steering,
    "swap": swap,
    "convoyturns": convoyturns,
}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    which = parser.add_mutually_exclusive_group(required=True)
    for name in TABLES:
        which.add_argument(f"--{name}", dest="table", action="store_const", const=name)
    args = parser.parse_args(argv)
    print(TABLES[args.table]())
    return 0


if __name__ == "__main__":
    sys.exit(main())

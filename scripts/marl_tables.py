"""The MARL comparison tables of docs/baselines.md (IPPO and MAPPO at 300k and 3M world
steps), from the runs' own files: each run's `baselines/<slug>/results.json` (its policy
on the task's 100 evaluation seeds, written by `bbbench train`) and `train.json`
(bot-steps, wall time), and the classical controller's episodes on the board
(`leaderboards/results/`).

    python scripts/marl_tables.py [--root baselines] [--board leaderboards] [--campaign]

`--campaign`: the tables of the field's budget (issue 50), IPPO and MAPPO at 3M world
steps on the five latest multi-bot and team tasks and issue 67's noisy-sensor and mixed
team tasks (a cell's row once a seed of it is trained), against the classical
controller and, on the crossing tasks, the crossing controller too. `--steering`: the steering
robot's baselines (issue 52), PPO on its single-bot tasks and IPPO and MAPPO at 3M on
Swap-v0 and ConvoyTurns-v0, each against its task's classical controller.

A row is one method on one task, its seeds side by side; a second table sets methods
against each other, every trained seed's episodes pooled. "P(> classical)" is rliable's
probability of improvement of the median seed's episodes over the controller's, with
its 95% stratified-bootstrap interval (`bbbench.evaluation.stats`, as the board ranks).
Seeds not trained yet are shown as "-".
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

import numpy as np

from bbbench.evaluation import stats
from bbbench.evaluation.results import normalized, read
from bbbench.policies import classical_controller
from bbbench.tasks.suite import scored_version, spec
from bbbench.training.logs import run_episodes

sys.path.insert(0, str(Path(__file__).parent))
from board_runs import CONTINUOUS, MUTED, SEEDS, cell_slug, short

BOARD = Path(__file__).resolve().parents[1] / "leaderboards"
# (task, method as the table names it, the slug of its runs without the seed suffix)
ROWS = (
    ("bbbench/MultiBalance-v1", "IPPO, encoder", "ippo-multibalance-v1"),
    ("bbbench/MultiBalance-v1", "IPPO, MLP actor", "ippo-mlp-multibalance-v1"),
    ("bbbench/MultiBalance-v1", "MAPPO, encoder", "mappo-multibalance-v1"),
    ("bbbench/MultiBalance-v1", "IPPO, encoder, gamma 0.995", "ippo-gamma995-multibalance-v1"),
    (
        "bbbench/MultiBalance-v1",
        "IPPO, encoder, gamma 0.995, twice the budget",
        "ippo-gamma995-2x-multibalance-v1",
    ),
    ("bbbench/BeamCarry-v0", "MAPPO, encoder", "mappo-beamcarry-v0"),
    ("bbbench/BeamCarry-v0", "MAPPO, MLP actor", "mappo-mlp-beamcarry-v0"),
    ("bbbench/BeamCarry-v0", "IPPO, encoder", "ippo-beamcarry-v0"),
    ("bbbench/MultiBumps-v1", "IPPO, encoder", "ippo-multibumps-v1"),
    ("bbbench/MultiBumps-v1", "MAPPO, encoder", "mappo-multibumps-v1"),
    ("bbbench/BeamCarryBumps-v0", "MAPPO, encoder", "mappo-beamcarrybumps-v0"),
    ("bbbench/BeamCarryBumps-v0", "IPPO, encoder", "ippo-beamcarrybumps-v0"),
    ("bbbench/Convoy-v0", "MAPPO, encoder", "mappo-convoy-v0"),
    ("bbbench/Convoy-v0", "IPPO, encoder", "ippo-convoy-v0"),
    ("bbbench/Convoy-v0", "MAPPO, encoder, lr 1e-4", "mappo-lr1e-4-convoy-v0"),
)
# The campaign at the field's budget: each task's IPPO and MAPPO cell.
CAMPAIGN_TASKS = (
    "bbbench/MultiBalance-v1",
    "bbbench/MultiBumps-v1",
    "bbbench/BeamCarry-v0",
    "bbbench/BeamCarryBumps-v0",
    "bbbench/Convoy-v0",
    # issue 67's: a bot's own noisy sensors, and the mixed team of two robots
    "bbbench/MultiNoisySensors-v0",
    "bbbench/MixedBeamCarry-v0",
    "bbbench/MixedBeamCarryBumps-v0",
)
# The tasks whose cells were trained at 300k first (issue 50), which the 3M cells are set
# against.
AT_300K = CAMPAIGN_TASKS[:5]
CAMPAIGN_ROWS = tuple(
    (task_id, f"{algo.upper()}, 3M", cell_slug(algo, task_id))
    for task_id in CAMPAIGN_TASKS
    for algo in ("ippo", "mappo")
)
CAMPAIGN_VERSUS = tuple(
    (task_id, what, first, second)
    for task_id in CAMPAIGN_TASKS
    for what, first, second in (
        ("MAPPO against IPPO, 3M", cell_slug("mappo", task_id), cell_slug("ippo", task_id)),
        *(  # the 300k cells' stem: the task's, without a budget
            (
                f"{algo.upper()}, 3M against 300k",
                cell_slug(algo, task_id),
                f"{algo}-{short(task_id).lower()}",
            )
            for algo in ("ippo", "mappo")
            if task_id in AT_300K
        ),
    )
)
# The steering robot's tasks: PPO on the single-bot ones, the campaign's cells on the others.
STEERING_SINGLE = ("bbbench/SteerTracking-v0", "bbbench/Waypoints-v0", "bbbench/WaypointsBumps-v0")
STEERING_MULTI = ("bbbench/Swap-v0", "bbbench/ConvoyTurns-v0", "bbbench/Rendezvous-v0")
STEERING_ROWS = (
    *(  # trained on these IDs, scored on their latest versions, which the board plays
        (on, f"PPO{trained_on}", f"ppo-{short(task_id).lower()}")
        for task_id in STEERING_SINGLE
        for on, trained_on in [scored_version(task_id)]
    ),
    *(
        (task_id, f"{algo.upper()}, 3M", cell_slug(algo, task_id))
        for task_id in STEERING_MULTI
        for algo in ("ippo", "mappo")
    ),
    # issue 67's run with the messages muted: what the channel is worth to the recipe
    ("bbbench/Rendezvous-v0", "MAPPO, 3M, messages muted", MUTED["cell"]),
    # and IPPO in continuous actions: whether the 243 discrete actions keep it from talking
    ("bbbench/Rendezvous-v0", "IPPO, 3M, continuous actions", CONTINUOUS["cell"]),
)
STEERING_VERSUS = (
    *(
        (task_id, "MAPPO against IPPO, 3M", cell_slug("mappo", task_id), cell_slug("ippo", task_id))
        for task_id in STEERING_MULTI
    ),
    (
        "bbbench/Rendezvous-v0",
        "MAPPO heard against muted, 3M",
        cell_slug("mappo", "bbbench/Rendezvous-v0"),
        MUTED["cell"],
    ),
    (
        "bbbench/Rendezvous-v0",
        "IPPO continuous against discrete, 3M",
        CONTINUOUS["cell"],
        cell_slug("ippo", "bbbench/Rendezvous-v0"),
    ),
)
# The crossing tasks' own controller, which the learned methods are also set against.
CROSSING = {"bbbench/MultiBalance-v1": "crossing", "bbbench/MultiBumps-v1": "crossing"}
# The comparisons: (task, what is compared, the first method's stem, the second's)
VERSUS = (
    (
        "bbbench/MultiBalance-v1",
        "encoder against MLP actor (IPPO)",
        "ippo-multibalance-v1",
        "ippo-mlp-multibalance-v1",
    ),
    (
        "bbbench/MultiBalance-v1",
        "MAPPO against IPPO",
        "mappo-multibalance-v1",
        "ippo-multibalance-v1",
    ),
    ("bbbench/BeamCarry-v0", "MAPPO against IPPO", "mappo-beamcarry-v0", "ippo-beamcarry-v0"),
    (
        "bbbench/BeamCarry-v0",
        "encoder against MLP actor (MAPPO)",
        "mappo-beamcarry-v0",
        "mappo-mlp-beamcarry-v0",
    ),
    ("bbbench/MultiBumps-v1", "MAPPO against IPPO", "mappo-multibumps-v1", "ippo-multibumps-v1"),
    (
        "bbbench/BeamCarryBumps-v0",
        "MAPPO against IPPO",
        "mappo-beamcarrybumps-v0",
        "ippo-beamcarrybumps-v0",
    ),
    ("bbbench/Convoy-v0", "MAPPO against IPPO", "mappo-convoy-v0", "ippo-convoy-v0"),
    (
        "bbbench/Convoy-v0",
        "lr 1e-4 against 3e-4 (MAPPO)",
        "mappo-lr1e-4-convoy-v0",
        "mappo-convoy-v0",
    ),
)


def episodes(results: dict, task_id: str) -> list[dict]:
    (block,) = [block for block in results["tasks"] if block["task"] == task_id]
    return block["episodes"]


def scores(played: list[dict], task_id: str) -> np.ndarray:
    return np.array([normalized(episode["return"], spec(task_id)) for episode in played])


def seed_runs(
    root: Path, task_id: str, stem: str, board: Path = BOARD
) -> dict[int, tuple[list[dict], dict]]:
    """Per trained seed: its episodes on the evaluation seeds and its train.json. The
    episodes are its training's own evaluation, or the board's (`board`'s results) once
    the board holds them, or on a task that training did not play (a later version)."""
    runs = {}
    for seed in SEEDS:
        folder = root / f"{stem}-s{seed}"
        played = run_episodes(folder, task_id, board) if folder.is_dir() else None
        if played is not None:
            runs[seed] = (played, json.loads((folder / "train.json").read_text()))
    return runs


def versus(root: Path, task_id: str, compared: str, first: str, second: str) -> str | None:
    """P(an episode of the first method > one of the second), every trained seed's
    episodes pooled, with its interval; the seeds each has."""
    a, b = seed_runs(root, task_id, first), seed_runs(root, task_id, second)
    if not a or not b:
        return None
    pooled = [
        np.concatenate([scores(played, task_id) for played, _ in runs.values()]) for runs in (a, b)
    ]
    point, (low, high) = stats.probability_of_improvement([pooled[0]], [pooled[1]])
    return (
        f"| {short(task_id)} | {compared} | {len(a)} / {len(b)} "
        f"| {pooled[0].mean():.3f} / {pooled[1].mean():.3f} | {point:.2f} [{low:.2f}, {high:.2f}] |"
    )


def against(board: Path, controller: str, task_id: str, played: list[dict]) -> str:
    """ "P [low, high] | the controller's mean normalized score" for `played` (the median
    seed's episodes) against the controller's episodes on the board."""
    document = read(board / "results" / f"{controller}.json")
    reference = scores(episodes(document, task_id), task_id)
    point, (low, high) = stats.probability_of_improvement([scores(played, task_id)], [reference])
    return f"{point:.2f} [{low:.2f}, {high:.2f}] | {reference.mean():.3f}"


def row(
    root: Path, board: Path, task_id: str, method: str, stem: str, crossing: bool = False
) -> str | None:
    runs = seed_runs(root, task_id, stem, board)
    if not runs:
        return None
    score = {seed: float(scores(played, task_id).mean()) for seed, (played, _) in runs.items()}
    minutes = {seed: record["wall_time_s"] / 60 for seed, (_, record) in runs.items()}
    # Bot-steps: a MARL run records them; a single-bot run's steps are its bot's.
    steps = {record.get("bot_steps") or record["steps"] for _, record in runs.values()}
    by_seed = " / ".join(f"{score[s]:.3f}" if s in score else "-" for s in SEEDS)
    walls = " / ".join(f"{minutes[s]:.1f}" if s in minutes else "-" for s in SEEDS)
    median_seed = sorted(score, key=score.get)[(len(score) - 1) // 2]
    played = [episode for episodes_, _ in runs.values() for episode in episodes_]
    whole = np.mean([episode["success"] for episode in played])
    median_played = runs[median_seed][0]
    columns = [against(board, classical_controller(task_id), task_id, median_played)]
    if crossing:
        known = task_id in CROSSING
        columns.append(
            against(board, CROSSING[task_id], task_id, median_played) if known else "- | -"
        )
    median = statistics.median(score.values())
    return (
        f"| {short(task_id)} | {method} | {max(steps) / 1e6:.1f}M | {walls} min "
        f"| {by_seed} | {median:.3f} | {whole:.0%} | {' | '.join(columns)} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=Path("baselines"))
    parser.add_argument("--board", type=Path, default=BOARD)
    which = parser.add_mutually_exclusive_group()
    which.add_argument(
        "--campaign", action="store_true", help="the tables of the 3M campaign (issue 50)"
    )
    which.add_argument(
        "--steering", action="store_true", help="the steering robot's baselines (issue 52)"
    )
    args = parser.parse_args()
    rows, compared = ROWS, VERSUS
    if args.campaign:
        rows, compared = CAMPAIGN_ROWS, CAMPAIGN_VERSUS
    elif args.steering:
        rows, compared = STEERING_ROWS, STEERING_VERSUS
    head = (
        "| task | method | bot-steps | wall time, by seed | normalized, by seed | median "
        "| no fall | P(median seed > classical) [95% CI] | classical |"
    )
    rule = "|---|---|---:|---:|---|---:|---:|---|---:|"
    if args.campaign:
        head += " P(median seed > crossing) [95% CI] | crossing |"
        rule += "---|---:|"
    print(head)
    print(rule)
    for task_id, method, stem in rows:
        line = row(args.root, args.board, task_id, method, stem, crossing=args.campaign)
        if line is not None:
            print(line)
    print()
    print("| task | compared | seeds | mean normalized, all seeds | P(first > second) [95% CI] |")
    print("|---|---|---:|---:|---|")
    for task_id, what, first, second in compared:
        line = versus(args.root, task_id, what, first, second)
        if line is not None:
            print(line)


if __name__ == "__main__":
    main()

"""The mixed team's calibration (issue 67): MixedBeamCarry-v0 and MixedBeamCarryBumps-v0
played by the random policy, `per-bot` (naive: each robot's own controller, a follower
holding the 0 it observes) and `mixed-team` (the team law on both robots,
`bbbench.policies.controllers.team`) on the 100 validation seeds, against the team
tasks' targets (scripts/calibrate_teams.py); and the choice it rests on, the
wheel-legged robots' leg length, on the first validation seeds.

    python scripts/calibrate_mixed.py --evaluate   # baselines/calibrations/mixed-team.json
    python scripts/calibrate_mixed.py --table      # docs/tasks.md's block, from the record
    python scripts/calibrate_mixed.py --legs 0.15 0.175 0.2 0.248 [--episodes 20]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from bbbench.envs.multi import MultiBalanceEnv
from bbbench.evaluation.play import MultiEpisode
from bbbench.policies import load_policy
from bbbench.policies.controllers.builtin import MixedTeamPolicy
from bbbench.tasks.spec import VALIDATION_SEEDS
from bbbench.tasks.suite import spec

sys.path.insert(0, str(Path(__file__).parent))
import calibrate_teams as teams  # the team tasks' targets, figures and table

MIXED_TASKS = ("bbbench/MixedBeamCarry-v0", "bbbench/MixedBeamCarryBumps-v0")
# The calibration's roles, played by these built-ins.
BUILT_IN = {"random": "random", "naive": "per-bot", "team": "mixed-team"}
RECORD = Path(__file__).parents[1] / "baselines" / "calibrations" / "mixed-team.json"


def play(job: tuple) -> tuple[int, float]:
    """(length, team return) of one episode: (task, role, seed), or (task, "team", seed,
    leg length) for the mixed team's law with the wheel-legged robots' legs at that length."""
    task_id, role, seed, *legs = job
    env = MultiBalanceEnv(spec(task_id))
    if legs:
        policy = MixedTeamPolicy(leg_length=legs[0])
    else:
        policy = load_policy(BUILT_IN[role], action_mode="continuous")
    rng = np.random.default_rng([0x5EED, seed]) if role == "random" else None
    result = MultiEpisode(env, policy.actor(task_id), seed, rng).play()
    env.close()
    return result.length, result.episode_return


def evaluate(workers: int) -> dict:
    """The record: both mixed tasks on their 100 validation seeds."""
    start = time.monotonic()
    with ProcessPoolExecutor(workers) as pool:
        tasks = {
            name: teams.figures(
                name, teams.POLICIES, VALIDATION_SEEDS, pool, play, spec(name).max_return
            )
            for name in MIXED_TASKS
        }
    extra = {"roles": BUILT_IN}
    return teams.validation_record(
        "the mixed team's tasks", extra, tasks, "calibrate_mixed.py", start
    )


def legs(lengths: list[float], episodes: int, workers: int) -> None:
    """The mixed team's mean return with each leg length, on the first validation seeds."""
    seeds = VALIDATION_SEEDS[:episodes]
    with ProcessPoolExecutor(workers) as pool:
        for task_id in MIXED_TASKS:
            jobs = [(task_id, "team", seed, length) for length in lengths for seed in seeds]
            played = list(pool.map(play, jobs, chunksize=4))
            for k, length in enumerate(lengths):
                mine = played[k * len(seeds) : (k + 1) * len(seeds)]
                finished = np.mean([n == 1500 for n, _ in mine])
                mean = np.mean([r for _, r in mine])
                print(f"{task_id} legs {length:g} m: {finished:.0%} finished, mean {mean:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--evaluate", action="store_true", help="write the record")
    parser.add_argument("--table", action="store_true", help="print docs/tasks.md's block")
    parser.add_argument("--legs", type=float, nargs="*", help="leg lengths to compare, m")
    parser.add_argument("--episodes", type=int, default=20, help="with --legs: seeds each")
    args = parser.parse_args()
    if args.legs:
        legs(args.legs, args.episodes, args.workers)
    if args.evaluate:
        RECORD.parent.mkdir(parents=True, exist_ok=True)
        partial = RECORD.with_suffix(".json.partial")
        partial.write_text(json.dumps(evaluate(args.workers), indent=1) + "\n")
        partial.replace(RECORD)
    if args.table:
        print(teams.table(json.loads(RECORD.read_text())))


if __name__ == "__main__":
    main()

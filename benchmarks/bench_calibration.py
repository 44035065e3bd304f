"""Terrain calibration: the PD baseline on each terrain task across its difficulties.

    python benchmarks/bench_calibration.py [--episodes 100] [--workers 2] [--tasks ID ...]

For each terrain task (default: the -v1 ones) and difficulty 0, 0.25, 0.5, 0.75,
1 and the task's default, the PD baseline plays the first `--episodes` evaluation
seeds. Printed per row: the success rate (episodes without a fall), the mean
return and the normalized score, (mean - random) / (max - random), where random is
the task's stored random return at its default difficulty (the random policy
falls on the level start pad within about 2 s, whatever the terrain beyond).
The table in docs/tasks.md is this script's output.
"""

from __future__ import annotations

import argparse
import multiprocessing
import statistics

import bbbench
from bbbench.envs.balance import BalanceEnv
from bbbench.policies import PDController
from bbbench.tasks.spec import TaskSpec

DIFFICULTIES = (0.0, 0.25, 0.5, 0.75, 1.0)
V1_TERRAIN = ("bbbench/Bumps-v1", "bbbench/Obstacles-v1", "bbbench/Slopes-v1")


def play_pd(task: TaskSpec, seeds: list[int]) -> list[tuple[bool, float]]:
    """(no fall, return) of the PD baseline on each seed."""
    env, policy = BalanceEnv(task), PDController()
    played = []
    for seed in seeds:
        observation, _ = env.reset(seed=seed)
        total = 0.0
        for _ in range(task.max_episode_steps):
            observation, reward, terminated, _, _ = env.step(policy(observation))
            total += reward
            if terminated:
                break
        played.append((not terminated, total))
    env.close()
    return played


def pd_outcomes(
    task: TaskSpec, episodes: int, pool: multiprocessing.pool.Pool, workers: int
) -> list[tuple[bool, float]]:
    seeds = list(task.eval_seeds[:episodes])
    n = workers  # one share of seeds per worker
    shares = [seeds[i::n] for i in range(n)]
    return [
        outcome for share in pool.starmap(play_pd, [(task, s) for s in shares]) for outcome in share
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--episodes", type=int, default=100, help="eval seeds per row")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--tasks", nargs="+", default=list(V1_TERRAIN))
    args = parser.parse_args()

    print(f"PD baseline, first {args.episodes} eval seeds per row")
    print("| task | difficulty | PD success | PD mean return | PD normalized |")
    print("|---|---|---|---|---|")
    with multiprocessing.Pool(args.workers) as pool:
        for task_id in args.tasks:
            spec = bbbench.spec(task_id)
            for difficulty in sorted({*DIFFICULTIES, spec.difficulty}):
                outcomes = pd_outcomes(
                    spec.with_difficulty(difficulty), args.episodes, pool, args.workers
                )
                success = statistics.fmean(ok for ok, _ in outcomes)
                mean = statistics.fmean(total for _, total in outcomes)
                normalized = (mean - spec.random_return) / (spec.max_return - spec.random_return)
                default = " (default)" if difficulty == spec.difficulty else ""
                print(
                    f"| {task_id} | {difficulty:g}{default} | {success:.0%} | {mean:.1f} "
                    f"| {normalized:.3f} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()

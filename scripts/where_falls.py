"""Where a multi-bot policy loses return against another: by the step, while its bots are
up (the velocity credit each up bot-step earns), or by its falls (each forfeits the rest
of a bot's episode), and how near the nearest other bot was just before each fall.

    python scripts/where_falls.py SLUG [SLUG ...] [--task bbbench/MultiBalance-v1]
                                  [--episodes 100]

Each SLUG names a run of the board (`pd`, `ippo-multibalance-v1-3m-s0`: a built-in, an ONNX
graph or an SB3 zip with its statistics), loaded and checked as `bbbench leaderboard
check` loads it; it plays the task's first `--episodes` evaluation seeds
deterministically, as `bbbench eval` plays them, and the output is one Markdown row per
entry. docs/notebook.md ("Where IPPO loses to PD") quotes it. Only the crossing tasks
(MultiBalance, MultiBumps): a team task's observation has another layout, and one bot's
fall ends the team.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import bbbench
from bbbench.leaderboard.submissions import read_methods
from bbbench.tasks.suite import spec

BOARD = Path(__file__).resolve().parents[1] / "leaderboards" / "submissions"

NEAR = 1.0  # m: a fall with another bot's torso this close is a fall in contact


@dataclass
class Tally:
    """What one policy's bots did, summed over its episodes."""

    bot_steps: int = 0  # steps a bot was up at the end of
    velocity_reward: float = 0.0  # the tracking share of their rewards
    near_steps: int = 0  # of them, with another bot within NEAR
    fall_distances: list[float] = field(default_factory=list)  # nearest bot, before each fall
    fall_steps: list[int] = field(default_factory=list)

    @property
    def falls(self) -> int:
        return len(self.fall_distances)

    def row(self, name: str, bots: int, episodes: int) -> str:
        near = sum(d < NEAR for d in self.fall_distances)
        median_step = int(np.median(self.fall_steps)) if self.fall_steps else "-"
        per_step = self.velocity_reward / self.bot_steps
        crowded = self.near_steps / self.bot_steps
        return (
            f"| {name} | {self.falls} of {bots * episodes} | {near} | {median_step} | "
            f"{per_step:.4f} | {crowded:.0%} |"
        )


def nearest(observation: np.ndarray) -> float:
    """The distance to the nearest bot in a multi-bot observation (slot 0: right and
    forward, m; zeros when no bot is in range): infinity when none is."""
    right, forward = float(observation[5]), float(observation[6])
    return float(np.hypot(right, forward)) if right or forward else float("inf")


def check_task(task_id: str) -> None:
    """Refuse a task whose falls this script would misread."""
    task = spec(task_id)
    if not task.multi_agent or task.coupling is not None:
        raise SystemExit(
            f"{task_id}: not a crossing task; where_falls reads MultiBalance's and "
            f"MultiBumps' layout, where each bot falls on its own"
        )


def tally(slug: str, task_id: str, seeds: list[int], board: Path = BOARD) -> Tally:
    """The board entry `slug`'s bots on the crossing task `task_id` over `seeds`."""
    check_task(task_id)
    runs = {run.slug: run for method in read_methods(board) for run in method.runs}
    if slug not in runs:
        raise SystemExit(f"{slug}: no such run on the board; the runs: {', '.join(sorted(runs))}")
    policy = runs[slug].load_policy()
    actor = policy.actor(task_id)
    counted = Tally()
    env = bbbench.make_parallel(task_id, action_mode=policy.action_mode)
    for seed in seeds:
        observations, _ = env.reset(seed=seed)
        while env.agents:
            agents = list(env.agents)
            actions = actor(np.stack([observations[agent] for agent in agents]))
            before = observations
            observations, _, terminations, _, infos = env.step(
                dict(zip(agents, actions, strict=True))
            )
            for agent in agents:
                if terminations[agent]:
                    counted.fall_distances.append(nearest(before[agent]))
                    counted.fall_steps.append(env.ended_at[agent])
                else:
                    counted.bot_steps += 1
                    counted.velocity_reward += infos[agent]["reward_velocity"]
                    counted.near_steps += nearest(observations[agent]) < NEAR
    env.close()
    return counted


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "slugs", nargs="+", help="runs of the board, e.g. pd ippo-multibalance-v1-3m-s0"
    )
    parser.add_argument("--task", default="bbbench/MultiBalance-v1")
    parser.add_argument("--episodes", type=int, default=100)
    args = parser.parse_args()
    check_task(args.task)
    task = spec(args.task)
    seeds = list(task.eval_seeds[: args.episodes])
    print(
        "| policy | falls (bot-episodes) | of them, a bot within 1 m | median step of a fall "
        "| velocity reward per up bot-step | up bot-steps with a bot within 1 m |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    for slug in args.slugs:
        print(tally(slug, args.task, seeds).row(slug, task.group.n_bots, len(seeds)))


if __name__ == "__main__":
    main()

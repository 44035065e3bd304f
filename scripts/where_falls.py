"""Where a multi-bot policy loses return against another: by the step, while its bots are
up (the velocity credit each up bot-step earns), or by its falls (each forfeits the rest
of a bot's episode), and how near the nearest other bot was just before each fall.

    python scripts/where_falls.py POLICY [POLICY ...] [--task bbbench/MultiBalance-v1]
                                  [--episodes 100]

Each POLICY (a built-in name, an ONNX file or an SB3 zip, with the `vecnormalize.pkl`
beside it if there is one, as the board keeps them) plays the task's first
`--episodes` evaluation seeds deterministically, as `bbbench eval` plays them; the output
is one Markdown row per policy. docs/baselines.md ("Where IPPO loses to PD") quotes it.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import bbbench
from bbbench.policies import load_policy
from bbbench.tasks.suite import spec

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


def tally(policy_name: str, task_id: str, seeds: list[int]) -> Tally:
    """`policy_name`'s bots on `task_id` over `seeds`."""
    statistics = Path(policy_name).with_name("vecnormalize.pkl")  # where the board keeps them
    beside = policy_name.endswith(".zip") and statistics.is_file()
    actor = load_policy(policy_name, vecnormalize=statistics if beside else None).actor(task_id)
    counted = Tally()
    for seed in seeds:
        env = bbbench.make_parallel(task_id, action_mode="discrete")
        observations, _ = env.reset(seed=seed)
        while env.agents:
            agents = list(env.agents)
            actions = actor(np.stack([observations[agent] for agent in agents]))
            before = observations
            observations, _, terminations, _, infos = env.step(
                {agent: int(action) for agent, action in zip(agents, actions, strict=True)}
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
    parser.add_argument("policies", nargs="+")
    parser.add_argument("--task", default="bbbench/MultiBalance-v1")
    parser.add_argument("--episodes", type=int, default=100)
    args = parser.parse_args()
    task = spec(args.task)
    seeds = list(task.eval_seeds[: args.episodes])
    print(
        "| policy | falls (bot-episodes) | of them, a bot within 1 m | median step of a fall "
        "| velocity reward per up bot-step | up bot-steps with a bot within 1 m |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    for name in args.policies:
        print(tally(name, args.task, seeds).row(name, task.group.n_bots, len(seeds)))


if __name__ == "__main__":
    main()

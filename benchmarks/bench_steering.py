"""The steering robot's tasks (issue 52) against the tasks they grew from.

    python benchmarks/bench_steering.py [--steps 60000] [--chunk 500] [--resets 100]

Three ratios, each between two loops measured side by side in alternating chunks (the
machine is shared and noisy; only ratios mean anything):

- a SteerTracking-v0 step against a VelocityTracking-v1 step (target: at most 1.05),
  each under its classical controller (`steer`, PD), through `gym.make` with its default
  wrappers; only `env.step` is timed, resets excluded;
- a new-terrain reset of WaypointsBumps-v0 (a 16 x 16 m patch, 0.1 m cells) against one
  of Bumps-v2 (a 2.4 x 24 m strip, 0.05 m cells), each `reset(seed=...)` to a new seed
  (target: at most 1.5); the first reset (the world's build) is not timed;
- a 4-bot Swap-v0 world step against a 4-bot MultiBalance-v1 world step (target: at most
  1.1), Swap under `steer-avoid` and MultiBalance under PD; only `env.step` is timed.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import bbbench
from bbbench.policies import load_policy

SEEDS = range(2**31, 2**31 + 100_000)


class SingleLoop:
    """A single-bot task under a built-in controller, timing `step` alone."""

    def __init__(self, task_id: str, controller: str) -> None:
        self.env = gym.make(task_id)
        self.actor = load_policy(controller).actor(task_id)
        self.seeds = iter(SEEDS)
        self.observation, _ = self.env.reset(seed=next(self.seeds))
        self.spent, self.steps = 0.0, 0

    def run(self, steps: int) -> None:
        env, actor = self.env, self.actor
        for _ in range(steps):
            action = actor(self.observation[None])[0]
            began = time.perf_counter()
            self.observation, _, terminated, truncated, _ = env.step(action)
            self.spent += time.perf_counter() - began
            self.steps += 1
            if terminated or truncated:
                self.observation, _ = env.reset(seed=next(self.seeds))


class MultiLoop:
    """A multi-bot task under a built-in controller, timing `step` alone."""

    def __init__(self, task_id: str, controller: str) -> None:
        self.env = bbbench.make_parallel(task_id, n_bots=4)
        self.actor = load_policy(controller).actor(task_id)
        self.seeds = iter(SEEDS)
        self.observations, _ = self.env.reset(seed=next(self.seeds))
        self.spent, self.steps = 0.0, 0

    def run(self, steps: int) -> None:
        env, actor = self.env, self.actor
        for _ in range(steps):
            agents = env.agents
            actions = actor(np.stack([self.observations[agent] for agent in agents]))
            began = time.perf_counter()
            self.observations, *_ = env.step(dict(zip(agents, actions, strict=True)))
            self.spent += time.perf_counter() - began
            self.steps += 1
            if not env.agents:
                self.observations, _ = env.reset(seed=next(self.seeds))


def compare(loops: dict, steps: int, chunk: int) -> list[tuple[str, float, float]]:
    """Run the loops in alternating chunks; each one's microseconds a step and its ratio
    to the first."""
    for _ in range(0, steps, chunk):
        for loop in loops.values():
            loop.run(chunk)
    per_step = {name: loop.spent / loop.steps for name, loop in loops.items()}
    reference = next(iter(per_step.values()))
    return [(name, 1e6 * value, value / reference) for name, value in per_step.items()]


def resets(task_ids: tuple[str, str], count: int) -> list[tuple[str, float, float]]:
    """Microseconds a new-terrain reset, alternating, and each one's ratio to the first."""
    envs = {task_id: gym.make(task_id) for task_id in task_ids}
    for env in envs.values():
        env.reset(seed=0)  # builds the world: not timed
    spent = dict.fromkeys(envs, 0.0)
    for seed in SEEDS[:count]:
        for task_id, env in envs.items():
            began = time.perf_counter()
            env.reset(seed=seed)
            spent[task_id] += time.perf_counter() - began
    reference = spent[task_ids[0]]
    return [(name, 1e6 * value / count, value / reference) for name, value in spent.items()]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=60_000, help="steps per loop")
    parser.add_argument("--chunk", type=int, default=500)
    parser.add_argument("--resets", type=int, default=100, help="resets per task")
    args = parser.parse_args()
    rows = compare(
        {
            "VelocityTracking-v1": SingleLoop("bbbench/VelocityTracking-v1", "pd"),
            "SteerTracking-v0": SingleLoop("bbbench/SteerTracking-v0", "steer"),
        },
        args.steps,
        args.chunk,
    )
    rows += resets(("bbbench/Bumps-v2", "bbbench/WaypointsBumps-v0"), args.resets)
    rows += compare(
        {
            "MultiBalance-v1 x4": MultiLoop("bbbench/MultiBalance-v1", "pd"),
            "Swap-v0 x4": MultiLoop("bbbench/Swap-v0", "steer-avoid"),
        },
        args.steps // 4,
        args.chunk,
    )
    print(f"{'what':28} {'us':>10} {'ratio':>6}")
    for name, microseconds, ratio in rows:
        print(f"{name.removeprefix('bbbench/'):28} {microseconds:10.2f} {ratio:6.3f}")


if __name__ == "__main__":
    main()

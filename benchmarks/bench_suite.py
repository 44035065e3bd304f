"""Suite benchmark: every single-bot task's step rate against FlatBalance-v0's.

    python benchmarks/bench_suite.py [--steps 30000] [--chunk 250] [--tasks ID ...] [--height-scan]
                                [--policy pd|random]

Each task is driven by the same policy on its evaluation seeds, resetting when an
episode ends: its robot's classical controller (default: the PD baseline, or the
wheel-legged robot's), or random actions (`--policy random`), the
start of training, where episodes last some 100 steps and resets weigh most. Only the
env's own time is counted (`step` and `reset`, policy excluded; also `step` alone), and
the tasks run alternately in chunks so they share the machine's slow and fast phases.
Also reports the mean time of a reset, which on terrain tasks draws and loads a new
terrain.
With `--height-scan`, each task is also timed with `height_scan=True` (a row
"ID +scan") in the same alternation, and the scan's cost per step is printed:
its step time over the same task's without it, less 1.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time

import gymnasium
import numpy as np

import bbbench
from bbbench.envs.balance import BalanceEnv
from bbbench.policies import load_policy
from bbbench.tasks.spec import TaskSpec

REFERENCE = "bbbench/FlatBalance-v0"


class RandomActions:
    """Uniform actions of the env's space from a seeded generator (the same sequence in
    every run): indices of a Discrete space, vectors in a Box."""

    def __init__(self, space: gymnasium.Space, seed: int = 0) -> None:
        self.rng = np.random.default_rng(seed)
        self.space = space
        self.actions: list = []

    def __call__(self, observation):
        if not self.actions:
            if isinstance(self.space, gymnasium.spaces.Discrete):
                self.actions = self.rng.integers(0, self.space.n, size=4096).tolist()
            else:
                size = (4096, *self.space.shape)
                values = self.rng.uniform(self.space.low, self.space.high, size=size)
                self.actions = list(values.astype(self.space.dtype))
        return self.actions.pop()


def classical_controller(task: TaskSpec):
    """The task's robot's classical controller (`Robot.controller`: PD, or the wheel-legged
    one), on one observation."""
    actor = load_policy(task.robot_model.controller).actor(task.id)
    return lambda observation: actor(observation[None])[0]


class TaskLoop:
    """One task under a policy (its robot's classical controller, or random actions),
    timing only the env's calls: a task ID's env as `bbbench.make` gives it (Gymnasium's
    wrappers included), or a spec's bare `BalanceEnv` (a row played by another robot)."""

    def __init__(self, task: str | TaskSpec, height_scan: bool = False, policy: str = "pd") -> None:
        if isinstance(task, str):
            self.env = bbbench.make(task, height_scan=height_scan)
            task = bbbench.spec(task)
        else:
            self.env = BalanceEnv(dataclasses.replace(task, height_scan=height_scan))
        if policy == "pd":
            self.policy = classical_controller(task)
        else:
            self.policy = RandomActions(self.env.action_space)
        self.seeds = iter(task.eval_seeds * 100)
        self.elapsed = 0.0  # step and reset
        self.stepping = 0.0  # step only
        self.steps = 0
        self.falls = 0
        self.episodes = 0
        self.reset_times: list[float] = []
        self.observation = self.reset()

    def reset(self):
        began = time.perf_counter()
        observation, _ = self.env.reset(seed=next(self.seeds))
        took = time.perf_counter() - began
        self.elapsed += took
        self.reset_times.append(took)
        self.episodes += 1
        return observation

    def run(self, steps: int) -> None:
        step, policy, observation = self.env.step, self.policy, self.observation
        for _ in range(steps):
            action = policy(observation)
            began = time.perf_counter()
            observation, _, terminated, truncated, _ = step(action)
            took = time.perf_counter() - began
            self.elapsed += took
            self.stepping += took
            if terminated or truncated:
                self.falls += terminated
                observation = self.reset()
        self.steps += steps
        self.observation = observation

    @property
    def step_time(self) -> float:
        """Mean seconds of `env.step`."""
        return self.stepping / self.steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=30_000, help="steps per task")
    parser.add_argument("--chunk", type=int, default=250, help="steps per alternation")
    parser.add_argument(
        "--tasks", nargs="+", help="task IDs to time (default: every single-bot task)"
    )
    parser.add_argument(
        "--height-scan", action="store_true", help="also time each task with height_scan=True"
    )
    parser.add_argument("--policy", choices=("pd", "random"), default="pd")
    args = parser.parse_args()

    task_ids = list(dict.fromkeys([REFERENCE, *(args.tasks or bbbench.list_tasks(False))]))
    loops = {task_id: TaskLoop(task_id, policy=args.policy) for task_id in task_ids}
    if args.height_scan:
        loops.update(
            {f"{task_id} +scan": TaskLoop(task_id, True, args.policy) for task_id in task_ids}
        )
    for _ in range(0, args.steps, args.chunk):
        for loop in loops.values():
            loop.run(args.chunk)
    reference = loops[REFERENCE].steps / loops[REFERENCE].elapsed
    step_reference = loops[REFERENCE].steps / loops[REFERENCE].stepping

    who = "classical-controller" if args.policy == "pd" else "random-action"
    print(
        f"Suite benchmark: {args.steps} {who} steps per task on its eval seeds, "
        f"alternating every {args.chunk} steps; env time only (step + reset)"
    )
    print(
        f"  {'task':34s} {'steps/s':>8s} {'x Flat':>7s} {'step only':>10s} {'x Flat':>7s} "
        f"{'reset ms':>9s} {'falls':>6s}"
    )
    for task_id, loop in loops.items():
        rate = loop.steps / loop.elapsed
        step_rate = loop.steps / loop.stepping
        reset_ms = 1e3 * statistics.fmean(loop.reset_times[1:] or loop.reset_times)
        print(
            f"  {task_id:34s} {rate:8.0f} {rate / reference:7.3f} {step_rate:10.0f} "
            f"{step_rate / step_reference:7.3f} {reset_ms:9.2f} "
            f"{loop.falls:>3d}/{loop.episodes - 1}"
        )
    if args.height_scan:
        print("  height scan, cost per step (step only):")
        for task_id in task_ids:
            blind, scanned = loops[task_id], loops[f"{task_id} +scan"]
            cost = (scanned.stepping / scanned.steps) / (blind.stepping / blind.steps) - 1.0
            print(f"    {task_id:28s} {cost:+7.1%}")
    print(
        "  targets: terrain tasks >= 0.7 x FlatBalance-v0; "
        "a reset that builds a new terrain <= 20 ms; the height scan <= 5% of a step"
    )


if __name__ == "__main__":
    main()

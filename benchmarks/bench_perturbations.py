"""What the perturbations that act during an episode cost a step: `push` and `action_delay`.

    python benchmarks/bench_perturbations.py [--steps 200000] [--chunk 250]

FlatBalance-v1 driven by PD (so the bot stays up and the steps are the same kind of
work), through `gym.make`, resets included, against the same task with `push=0.5`
(a shove every 2-4 s), `action_delay=3`, `push=1e-9` (the push's bookkeeping and
pybullet calls without its physics) and `action_delay=1`, the loops alternating in
chunks so that they share the machine's slow and fast phases. Prints each one's time
per step as a ratio to the plain task's, and the difference as a share of a
FlatBalance step (the target: at most 3%).
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym

import bbbench  # noqa: F401 (registers the tasks)
from bbbench.policies import PDController

TASK = "bbbench/FlatBalance-v1"
VARIANTS = {
    "plain": {},
    "push=0.5": {"push": 0.5},
    "push=1e-9": {"push": 1e-9},
    "action_delay=3": {"action_delay": 3},
    "action_delay=1": {"action_delay": 1},
}


class PDLoop:
    """The task under PD, reset as episodes end (training seeds, from reset(seed=0) on)."""

    def __init__(self, **options) -> None:
        self.env = gym.make(TASK, **options)
        self.observation, _ = self.env.reset(seed=0)
        self.policy = PDController()
        self.steps = self.episodes = 0

    def run(self, steps: int) -> None:
        env, policy, observation = self.env, self.policy, self.observation
        for _ in range(steps):
            observation, _, terminated, truncated, _ = env.step(policy(observation))
            if terminated or truncated:
                observation, _ = env.reset()
                self.episodes += 1
        self.observation = observation
        self.steps += steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--chunk", type=int, default=250)
    args = parser.parse_args()
    loops = {name: PDLoop(**options) for name, options in VARIANTS.items()}
    totals = dict.fromkeys(loops, 0.0)
    for _ in range(args.steps // args.chunk):
        for name, loop in loops.items():
            began = time.perf_counter()
            loop.run(args.chunk)
            totals[name] += time.perf_counter() - began
    plain = totals["plain"] / loops["plain"].steps
    print(f"{TASK} under PD, {args.steps} steps per loop, chunks of {args.chunk}")
    print(f"plain: {plain * 1e6:.1f} us per step ({loops['plain'].episodes} resets)")
    for name, loop in loops.items():
        if name == "plain":
            continue
        per_step = totals[name] / loop.steps
        print(
            f"{name}: {per_step * 1e6:.1f} us per step, {per_step / plain:.3f}x plain, "
            f"{(per_step - plain) / plain:+.1%} of a step ({loop.episodes} resets)"
        )


if __name__ == "__main__":
    main()

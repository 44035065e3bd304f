"""The message task's step against Swap-v0's at the same number of bots (issue 67: at most
1.15).

    python benchmarks/bench_channel.py [--bots 4 8] [--bot-steps 30000] [--chunk 3000]

Each task in one process, its classical controller acting (rendezvous; steer-avoid on
Swap), only the env's `step` timed (resets and the controllers excluded); the two tasks
take turns in chunks of bot-steps, so they share the machine's slow and fast phases. The
ratio is Rendezvous-v0's seconds per bot-step over Swap-v0's: what the landmarks, the
scout's one-hot, the team reward and the channel's message block cost beside Swap's goal
and neighbour block.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import bbbench
from bbbench.policies import load_policy

TASKS = (("bbbench/Rendezvous-v0", "rendezvous"), ("bbbench/Swap-v0", "steer-avoid"))


class Loop:
    """One task's env under its controller, stepped a chunk of bot-steps at a time (a
    mixed team's controller acting group by group, as the play loop does)."""

    def __init__(self, task_id: str, controller: str, bots: int, **options) -> None:
        self.env = bbbench.make_parallel(task_id, n_bots=bots, **options)
        self.act = load_policy(controller, **options).actor(task_id)
        self.seeds = iter(bbbench.spec(task_id).eval_seeds * 1000)
        self.observations, _ = self.env.reset(seed=next(self.seeds))
        self.spent, self.done = 0.0, 0

    def run(self, bot_steps: int) -> None:
        env, goal = self.env, self.done + bot_steps
        while self.done < goal:
            agents = env.agents
            rows = [self.observations[agent] for agent in agents]
            if env.task.mixed:
                acted = self.act.team(rows, [env.agent_index[agent] for agent in agents])
            else:
                acted = self.act(np.stack(rows), None)
            actions = dict(zip(agents, acted, strict=True))
            began = time.perf_counter()
            self.observations, *_ = env.step(actions)
            self.spent += time.perf_counter() - began
            self.done += len(agents)
            if not env.agents:
                self.observations, _ = env.reset(seed=next(self.seeds))

    @property
    def per_bot_step(self) -> float:
        return self.spent / self.done


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bots", type=int, nargs="*", default=[4, 8])
    parser.add_argument("--bot-steps", type=int, default=30_000)
    parser.add_argument("--chunk", type=int, default=3_000)
    args = parser.parse_args()
    print("bots | Rendezvous-v0 us/bot-step | Swap-v0 us/bot-step | ratio")
    for bots in args.bots:
        loops = [Loop(task_id, controller, bots) for task_id, controller in TASKS]
        talk, swap = in_turns(loops, args.bot_steps, args.chunk)
        print(f"{bots} | {talk * 1e6:.1f} | {swap * 1e6:.1f} | {talk / swap:.3f}")


def in_turns(loops: list[Loop], bot_steps: int, chunk: int) -> list[float]:
    """Each loop's seconds per bot-step, the loops stepped in turns of `chunk` bot-steps
    until each has `bot_steps` (after a chunk each to warm up)."""
    for loop in loops:
        loop.run(chunk)  # warm up, then start the clocks again
        loop.spent, loop.done = 0.0, 0
    while min(loop.done for loop in loops) < bot_steps:
        for loop in loops:
            loop.run(chunk)
    return [loop.per_bot_step for loop in loops]


if __name__ == "__main__":
    main()

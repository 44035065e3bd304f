"""Coupled teams (issue 39): a 3-bot column step against a 3-bot MultiBalance-v1 step.

    python bench/bench_teams.py [--steps 30000] [--chunk 250]

Three worlds of 3 bots, each driven by PD on every bot (the team controller on the
column tasks: the same PD, a few more Python operations an observation), stepped in
alternating chunks so they share the machine's slow and fast phases; only `env.step` is
timed, resets excluded. The column tasks are made here from MultiBalance-v1's row (their
suite rows come with their calibration): a 1.5 kg beam (`BeamCarry`) and tethers
(`Convoy`), targets in [-2, 2] m/s. Reported: microseconds per world-step and the ratio
to MultiBalance-v1's (the issue's targets: at most 1.3 for the beam, 1.5 for the convoy).
"""

from __future__ import annotations

import argparse
import time

import bbbench
from bbbench.dev.teams import candidate_task
from bbbench.envs.multi import MultiBalanceEnv
from bbbench.policies.pd import PDController
from bbbench.policies.team import TeamController
from bbbench.tasks.coupling import Beam, Tether


def column(coupling) -> MultiBalanceEnv:
    return MultiBalanceEnv(candidate_task(coupling, 3, 2.0, task_id="bbbench/TeamBench-v0"))


class Loop:
    """One env under a controller, timing `step` alone."""

    def __init__(self, env: MultiBalanceEnv, control) -> None:
        self.env, self.control = env, control
        self.seeds = iter(range(2**31, 2**31 + 10_000))
        self.observations, _ = env.reset(seed=next(self.seeds))
        self.spent, self.steps = 0.0, 0

    def run(self, steps: int) -> None:
        env, control = self.env, self.control
        for _ in range(steps):
            actions = {agent: control(self.observations[agent]) for agent in env.agents}
            began = time.perf_counter()
            self.observations, *_ = env.step(actions)
            self.spent += time.perf_counter() - began
            self.steps += 1
            if not env.agents:
                self.observations, _ = env.reset(seed=next(self.seeds))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=30_000, help="world-steps per task")
    parser.add_argument("--chunk", type=int, default=250)
    args = parser.parse_args()
    pd = PDController()
    plain = bbbench.make_parallel("bbbench/MultiBalance-v1", n_bots=3)
    beam, convoy = column(Beam()), column(Tether())
    loops = {
        "MultiBalance-v1 x3": Loop(plain, lambda observation: pd(observation[:5])),
        "BeamCarry x3": Loop(beam, TeamController([f.name for f in beam.scene.scenario.layout])),
        "Convoy x3": Loop(convoy, TeamController([f.name for f in convoy.scene.scenario.layout])),
    }
    for _ in range(0, args.steps, args.chunk):
        for loop in loops.values():
            loop.run(args.chunk)
    reference = loops["MultiBalance-v1 x3"].spent / loops["MultiBalance-v1 x3"].steps
    print(f"{'task':22} {'us/world-step':>14} {'ratio':>6}")
    for name, loop in loops.items():
        per_step = loop.spent / loop.steps
        print(f"{name:22} {1e6 * per_step:14.2f} {per_step / reference:6.3f}")


if __name__ == "__main__":
    main()

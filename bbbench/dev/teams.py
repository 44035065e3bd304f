"""Candidate column tasks, before they are rows of the suite: MultiBalance-v1's row with a
column scenario (`bbbench.tasks.scenarios.column`) and a coupling. The calibration
(scripts/calibrate_teams.py), the bench (benchmarks/bench_teams.py) and the tests play them."""

from __future__ import annotations

import dataclasses
from typing import Any

from bbbench.tasks.commands import PiecewiseConstantVelocity
from bbbench.tasks.group import Group
from bbbench.tasks.scenarios import Beam, Tether
from bbbench.tasks.spec import TaskSpec
from bbbench.tasks.suite import SUITE


def candidate_task(
    coupling: Beam | Tether,
    n_bots: int = 3,
    speed: float = 2.0,
    task_id: str = "bbbench/TeamCandidate-v0",
    **changes: Any,
) -> TaskSpec:
    """A team of `n_bots` coupled by `coupling` (a beam: BeamCarry; tethers: Convoy),
    following targets drawn from [-speed, speed] m/s and held 2-5 s; `changes` replace any
    other field of the spec."""
    scenario = "beam-carry" if isinstance(coupling, Beam) else "convoy"
    fields = {
        "id": task_id,
        "scenario": scenario,
        "coupling": coupling,
        "group": Group(n_bots=n_bots),
        "command": PiecewiseConstantVelocity(low=-speed, high=speed, hold=(2.0, 5.0)),
        "random_return": None,
    }
    return dataclasses.replace(SUITE["bbbench/MultiBalance-v1"], **{**fields, **changes})

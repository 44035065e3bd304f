"""The scenarios: each task's rules (`Scenario`), found by the name its spec gives, and
beside each scenario the tasks it plays, a row each (its module's `TASKS`).

`TASKS` is every row, scenario by scenario, in the order each module lists them; the
suite (`bbbench.tasks.suite`) registers them. A new scenario is a module here, named in
`MODULES`.
"""

from bbbench.tasks.scenario import SCENARIOS, Scenario, scenario

# In the suite's order: each module registers its scenario, then makes its rows.
from bbbench.tasks.scenarios import solo
from bbbench.tasks.scenarios import crossing
from bbbench.tasks.scenarios import beam_carry
from bbbench.tasks.scenarios import convoy
from bbbench.tasks.scenarios import steer
from bbbench.tasks.scenarios import waypoints
from bbbench.tasks.scenarios import swap
from bbbench.tasks.scenarios import rendezvous
from bbbench.tasks.scenarios import mixed_team
from bbbench.tasks.scenarios.beam_carry import Beam, BeamCarry
from bbbench.tasks.scenarios.column import Column
from bbbench.tasks.scenarios.convoy import Convoy, ConvoyTurns, Tether
from bbbench.tasks.scenarios.crossing import Crossing
from bbbench.tasks.scenarios.mixed_team import MixedBeamCarry
from bbbench.tasks.scenarios.rendezvous import Rendezvous
from bbbench.tasks.scenarios.solo import Solo
from bbbench.tasks.scenarios.steer import Steer
from bbbench.tasks.scenarios.swap import Swap
from bbbench.tasks.scenarios.waypoints import Waypoints

MODULES = (solo, crossing, beam_carry, convoy, steer, waypoints, swap, rendezvous, mixed_team)
TASKS = tuple(task for module in MODULES for task in module.TASKS)

__all__ = [
    "MODULES",
    "SCENARIOS",
    "TASKS",
    "Beam",
    "BeamCarry",
    "Column",
    "Convoy",
    "ConvoyTurns",
    "Crossing",
    "MixedBeamCarry",
    "Rendezvous",
    "Scenario",
    "Solo",
    "Steer",
    "Swap",
    "Tether",
    "Waypoints",
    "scenario",
]

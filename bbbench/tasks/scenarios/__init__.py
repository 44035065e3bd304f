"""The scenarios: each task's rules (`Scenario`), found by the name its spec gives."""

from bbbench.tasks.scenarios.base import Scenario
from bbbench.tasks.scenarios.column import BeamCarry, Column, Convoy
from bbbench.tasks.scenarios.crossing import Crossing
from bbbench.tasks.scenarios.solo import Solo

SCENARIOS: dict[str, type[Scenario]] = {
    cls.name: cls for cls in (Solo, Crossing, BeamCarry, Convoy)
}


def scenario(name: str) -> type[Scenario]:
    """The scenario called `name` (`TaskSpec.scenario`), or a KeyError that lists them."""
    try:
        return SCENARIOS[name]
    except KeyError:
        raise KeyError(f"no scenario {name!r}: the scenarios are {', '.join(SCENARIOS)}") from None


__all__ = ["SCENARIOS", "BeamCarry", "Column", "Convoy", "Crossing", "Scenario", "Solo", "scenario"]

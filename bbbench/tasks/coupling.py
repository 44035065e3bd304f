"""What couples a team of bots: a beam they carry together, or tethers from each bot to
the next. The parameters of the column scenarios (`bbbench.tasks.scenarios.column`),
held by a task's spec (`TaskSpec.coupling`) and so hashed into its fingerprint."""

from __future__ import annotations

import math

from bbbench.parameters import is_real, parameters

MAX_TEAM = 4  # bots in a coupled column: the beam and tether tasks take 2 to 4


def _check(component: object, ranges: dict[str, tuple[float, float]], units: dict[str, str]):
    """A ValueError naming the first parameter outside its physical range."""
    name = type(component).__name__
    for field, (low, high) in ranges.items():
        value = getattr(component, field)
        if not is_real(value) or not math.isfinite(value) or not low <= value <= high:
            raise ValueError(
                f"{name} {field} must be a number in [{low:g}, {high:g}] {units[field]}, "
                f"got {value!r}"
            )
        object.__setattr__(component, field, float(value))


@parameters
class Beam:
    """A rigid beam carried by the column, hinged to the top of every torso.

    The beam is a box `width` across (along the axles), `thickness` high, and long
    enough to reach `overhang` m beyond the first and the last hinge: (N - 1) x
    `spacing` + 2 x `overhang` m for N bots. Each bot holds it by two point-to-point
    constraints `hinge_span` m apart along its axle, at the top of its torso: a hinge
    that leaves only pitch free (a single ball joint lets a bot that cannot steer spin
    about it). The beam collides with the ground only.
    """

    mass: float = 1.5  # kg
    spacing: float = 0.6  # m between neighbouring bots' hinges along the beam
    overhang: float = 0.1  # m beyond the first and the last hinge
    width: float = 0.3  # m, along the axles
    thickness: float = 0.04  # m
    hinge_span: float = 0.2  # m between a bot's two hinge points, along its axle

    def __post_init__(self) -> None:
        ranges = {
            "mass": (0.1, 10.0),
            "spacing": (0.4, 2.0),  # wheels 0.24 m apart: columns closer than 0.4 m collide
            "overhang": (0.0, 1.0),
            "width": (0.05, 1.0),
            "thickness": (0.01, 0.2),
            "hinge_span": (0.02, 0.24),  # within the torso's 0.2 m width, near enough
        }
        units = dict.fromkeys(ranges, "m") | {"mass": "kg"}
        _check(self, ranges, units)

    def length(self, n_bots: int) -> float:
        """m: the beam of a column of `n_bots`."""
        return (n_bots - 1) * self.spacing + 2 * self.overhang


@parameters
class Tether:
    """A spring-damper from each bot to the next in the column, between their torsos'
    centres of mass: a pull of `stiffness` x (distance - `rest_length`) + `damping` x
    (its rate), along the line between them, applied to both before every world step.
    A tether stretched more than `breaking_stretch` beyond its rest length breaks, and
    ends the team's episode."""

    stiffness: float = 20.0  # N/m
    damping: float = 5.0  # N s/m
    rest_length: float = 0.6  # m: the bots start this far apart
    breaking_stretch: float = 0.4  # m beyond the rest length

    def __post_init__(self) -> None:
        ranges = {
            "stiffness": (0.0, 500.0),
            "damping": (0.0, 100.0),
            "rest_length": (0.4, 5.0),
            "breaking_stretch": (0.01, 5.0),
        }
        units = {
            "stiffness": "N/m",
            "damping": "N s/m",
            "rest_length": "m",
            "breaking_stretch": "m",
        }
        _check(self, ranges, units)

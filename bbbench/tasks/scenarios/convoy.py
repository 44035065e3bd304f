"""`Convoy`: a column of bots each tethered to the next; the tether's parameters
(`Tether`), and the task played with it (Convoy-v0)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pybullet

from bbbench.parameters import parameters
from bbbench.portable import dot3, total
from bbbench.robots.layout import GYRO_RANGE, OBSERVATION_DTYPE, ObservationField
from bbbench.tasks.commands import PiecewiseConstantTwist
from bbbench.tasks.group import Group
from bbbench.tasks.reward import StayUpReward, TwistReward
from bbbench.tasks.scenario import register_scenario
from bbbench.tasks.scenarios.column import (
    PARKED,
    TEAM_HISTORY,
    TEAM_TARGETS,
    Column,
    check_ranges,
    team_description,
)
from bbbench.tasks.spec import TaskSpec

STRETCH_RANGE = 5.0  # m
STRETCH_RATE_RANGE = 10.0  # m/s
_BEADS_PER_TETHER = 12  # what a frame shows of a tether


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
        check_ranges(self, ranges, units)


@register_scenario
class Convoy(Column):
    """Each bot is tethered to the next (`Tether`): a spring-damper between torso
    centres that pulls when stretched beyond its rest length (a tether never pushes).
    Each bot observes the stretch of the tether ahead and of the one behind, and their
    rates (0 where there is none). The team's velocity is the bots' mean forward velocity.
    A tether stretched past its breaking stretch ends the episode."""

    name = "convoy"
    summary = "a column of bots each tethered to the next, led by the front bot"
    coupling_type = Tether
    coupling_layout = (
        ObservationField(
            "stretch_ahead",
            "m",
            -STRETCH_RANGE,
            STRETCH_RANGE,
            "the tether ahead: length beyond its rest length",
        ),
        ObservationField(
            "stretch_rate_ahead", "m/s", -STRETCH_RATE_RANGE, STRETCH_RATE_RANGE, "its rate"
        ),
        ObservationField(
            "stretch_behind", "m", -STRETCH_RANGE, STRETCH_RANGE, "the tether behind, the same"
        ),
        ObservationField(
            "stretch_rate_behind", "m/s", -STRETCH_RATE_RANGE, STRETCH_RATE_RANGE, "its rate"
        ),
    )

    @staticmethod
    def coupling_spacing(coupling: Tether) -> float:
        return coupling.rest_length

    def build(self, client, bots) -> None:
        super().build(client, bots)
        self._beads: list[list[int]] = []  # per tether, what `draw` shows of it

    def draw(self, scene) -> None:
        """Each tether as a line of beads between the torsos' centres: grey while slack,
        turning red as it stretches towards its breaking stretch. Bodies without mass or
        collision shape, made at the first frame."""
        client = self._client
        if not self._beads:
            bead = client.createVisualShape(pybullet.GEOM_SPHERE, radius=0.015)
            self._beads = [
                [client.createMultiBody(0.0, -1, bead, PARKED) for _ in range(_BEADS_PER_TETHER)]
                for _ in self._tethers
            ]
        positions, limit = self._positions, self.coupling.breaking_stretch
        for j, (beads, (_, stretch, _)) in enumerate(zip(self._beads, self._tethers, strict=True)):
            strain = min(max(stretch / limit, 0.0), 1.0)
            colour = (0.5 + 0.5 * strain, 0.5 * (1.0 - strain), 0.5 * (1.0 - strain), 1.0)
            for k, body in enumerate(beads):
                along = (k + 1) / (len(beads) + 1)
                point = [a + along * (b - a) for a, b in zip(*positions[j : j + 2], strict=True)]
                client.resetBasePositionAndOrientation(body, point, (0.0, 0.0, 0.0, 1.0))
                client.changeVisualShape(body, -1, rgbaColor=colour)

    def read(self, states: list[Any]) -> None:
        """Each tether's direction, stretch and rate, from the bots' centres of mass."""
        client_id, rest = self._client_id, self.coupling.rest_length
        velocities = [pybullet.getBaseVelocity(body, client_id)[0] for body in self._bodies]
        positions = [pybullet.getBasePositionAndOrientation(b, client_id)[0] for b in self._bodies]
        self._positions = positions  # where `before_step` and `draw` find the bots
        tethers = []
        for j in range(len(positions) - 1):
            delta = np.subtract(positions[j + 1], positions[j])
            # dot3, not np.dot / np.linalg.norm: BLAS's rounding varies with the CPU.
            length = math.sqrt(dot3(delta, delta)) or 1e-9
            direction = delta / length  # from bot j to bot j + 1
            rate = dot3(np.subtract(velocities[j + 1], velocities[j]), direction)
            tethers.append((direction, length - rest, rate))
        self._tethers = tethers

    @property
    def tethers(self) -> tuple[tuple[np.ndarray, float, float], ...]:
        """Each tether's reading, front to back, as of the last `observe`: its direction
        (from bot j to bot j + 1), its stretch past the rest length (m) and its rate
        (m/s)."""
        return tuple(self._tethers)

    @property
    def beads(self) -> tuple[tuple[int, ...], ...]:
        """Per tether, the bodies `draw` shows it with (none before the first frame)."""
        return tuple(map(tuple, self._beads))

    def coupling_terms(self, index: int) -> list[float]:
        terms = []
        for j in (index - 1, index):  # the tether ahead joins bot index - 1 and index
            if 0 <= j < len(self._tethers):
                _, stretch, rate = self._tethers[j]
                terms += [
                    min(max(stretch, -STRETCH_RANGE), STRETCH_RANGE),
                    min(max(rate, -STRETCH_RATE_RANGE), STRETCH_RATE_RANGE),
                ]
            else:
                terms += [0.0, 0.0]
        return terms

    def before_step(self, scene) -> None:
        """Each stretched tether pulls its two bots together: k x stretch + c x rate, at
        their centres of mass, from the last reading (`read`, after the last step: nothing
        has moved since)."""
        tether, client_id = self.coupling, self._client_id
        bodies, positions = self._bodies, self._positions
        for j, (direction, stretch, rate) in enumerate(self._tethers):
            if stretch <= 0.0:
                continue
            pull = max(0.0, tether.stiffness * stretch + tether.damping * rate)
            force = (pull * direction).tolist()
            back = (-pull * direction).tolist()
            for k, push in ((j, force), (j + 1, back)):
                pybullet.applyExternalForce(
                    bodies[k], -1, push, positions[k], pybullet.WORLD_FRAME,
                    physicsClientId=client_id,
                )  # fmt: skip

    broken_cause = "a tether broke"
    pull_forward = "stretch_ahead"

    def broken(self) -> bool:
        limit = self.coupling.breaking_stretch
        return any(stretch > limit for _, stretch, _ in self._tethers)

    def team_velocity(self, states: list[Any]) -> float:
        return total(state.forward_velocity for state in states) / len(states)


TARGET_YAW_RATE = ObservationField(
    "target_yaw_rate", "rad/s", -GYRO_RANGE, GYRO_RANGE, "the yaw rate the front bot is asked for"
)


@register_scenario
class ConvoyTurns(Convoy):
    """`Convoy` for the steering robot, its front bot commanded a velocity and a yaw rate
    (`PiecewiseConstantTwist`): the column must follow its front bot through turns. Each
    bot observes its robot's layout, then the target yaw rate (the front bot's; 0 for the
    others, as their target velocity), then Convoy's tethers and neighbours. The team's
    reward is `TwistReward.terms` with the most tilted bot's pitch, the team's mean
    forward velocity against the target velocity, and the front bot's yaw rate against
    the target yaw rate."""

    name = "convoy-turns"
    summary = "a tethered column of steering bots following its front bot through turns"
    robots = ("two-wheel-steer",)
    steers = True
    metrics = ("velocity_error", "yaw_rate_error")

    def __init__(self, task) -> None:
        super().__init__(task)
        own = len(self.robot.layout())
        self.layout = (*self.layout[:own], TARGET_YAW_RATE, *self.layout[own:])

    def observe(
        self, scene: Any, states: list[Any], commands: list[float], targets: list[Any], step: int
    ) -> np.ndarray:
        """Convoy's rows with the front bot's target velocity in the robot's slot and its
        target yaw rate after the robot's values (0 and 0 for the followers)."""
        velocity, yaw_rate = targets[0]
        rows = super().observe(scene, states, commands, [velocity] * len(states), step)
        own = len(self.robot.layout())
        yaw_rates = np.zeros((len(states), 1), dtype=OBSERVATION_DTYPE)
        yaw_rates[0, 0] = min(max(yaw_rate, -GYRO_RANGE), GYRO_RANGE)
        return np.concatenate([rows[:, :own], yaw_rates, rows[:, own:]], axis=1)

    def scored(
        self, pitch: float, states: list[Any], target: Any
    ) -> tuple[float, float, dict[str, float]]:
        """`TwistReward.terms` (the class's docstring): the team's velocity against the
        target velocity, the front bot's yaw rate against the target yaw rate."""
        velocity, yaw_rate = target
        velocity_error = abs(self.team_velocity(states) - velocity)
        yaw_rate_error = abs(states[0].yaw_rate - yaw_rate)
        upright, tracking = self.reward.terms(pitch, velocity_error, yaw_rate_error)
        return (
            upright,
            tracking,
            {"velocity_error": velocity_error, "yaw_rate_error": yaw_rate_error},
        )


# What ConvoyTurns shares with the two-wheel team tasks, in its own robot's terms.
_TURNS_WHY = """\
Only the front bot observes the team's target velocity and yaw rate; the others read 0 in
those slots and must infer them from the tethers and from their neighbours. Every agent
receives the team's reward, and a fall of any bot ends every agent's episode. The
observation has 23 values per bot (`Box(23,)`, the actions `Discrete(27)`). The classical
team controller is `team` (`bbbench.policies.controllers.team`; `pd`, a controller of the
two-wheel bot, does not play this robot); docs/tasks.md has the calibration."""


# The tasks it plays: each row states all it sets (`TaskSpec`'s defaults for the rest).
TASKS = (
    TaskSpec(
        id="bbbench/Convoy-v0",
        summary="a convoy of 3 bots (2-4), each tethered to the next, led by the front bot",
        description=team_description(
            """\
A column of bots (3 by default, `n_bots` 2-4) on one heading, each tethered to the next
by a spring-damper between their torsos' centres of mass (`Convoy`, `Tether`) on flat
ground. A tether pulls, never pushes: 20 N/m x (length - 0.6 m) + 5 N s/m x (its rate),
applied to both bots before every world step; stretched more than 0.4 m beyond its rest
length it breaks, and the team's episode ends. The bots start 0.6 m apart (the rest
length). The team's velocity is the bots' mean forward velocity. Each bot observes the
stretch of the tether ahead and of the one behind, and their rates (0 where there is
none)."""
        ),
        reward=StayUpReward(),
        group=Group(n_bots=3),
        command=TEAM_TARGETS,
        scenario="convoy",
        coupling=Tether(),
        version_history=TEAM_HISTORY,
        random_return=0.9912909542770169,
    ),
    TaskSpec(
        id="bbbench/ConvoyTurns-v0",
        summary="a tethered convoy of 3 steering bots (2-4) following its front bot through turns",
        description=team_description(
            """\
Convoy-v0's column of tethered bots (3 by default, `n_bots` 2-4; the same tethers) made
of steering robots, on flat ground. The front bot is commanded a velocity in [-2, 2] m/s
(Convoy's) and a yaw rate in [-2, 2] rad/s (`PiecewiseConstantTwist`), the pair held 2-5 s;
the others observe 0 in both slots and must follow it through the turns. The team's
reward is `TwistReward.terms` with the most tilted bot's pitch, the team's mean forward
velocity against the target velocity and the front bot's yaw rate against the target
yaw rate: each step earns 0-0.1. Each bot observes the steering robot's eight values,
the target yaw rate, the stretch of the tether ahead and of the one behind and their
rates, then the bots ahead and behind.""",
            _TURNS_WHY,
        ),
        robot="two-wheel-steer",
        reward=TwistReward(),
        group=Group(n_bots=3),
        command=PiecewiseConstantTwist(
            low=-2.0, high=2.0, yaw_low=-2.0, yaw_high=2.0, hold=(2.0, 5.0)
        ),
        scenario="convoy-turns",
        coupling=Tether(),
        version_history=("v0: initial release.",),
        random_return=1.072511704615297,
    ),
)

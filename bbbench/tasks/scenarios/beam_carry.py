"""`BeamCarry`: a column of bots carrying one beam hinged to the top of every torso;
the beam's parameters (`Beam`), and the tasks played with it (BeamCarry-v0,
BeamCarryBumps-v0)."""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
import pybullet

from bbbench.parameters import parameters
from bbbench.portable import total
from bbbench.robots.layout import GYRO_RANGE, ObservationField
from bbbench.tasks.group import Group
from bbbench.tasks.reward import StayUpReward
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
from bbbench.terrain import Bumps, HeightfieldTerrain

HINGE_FORCE_RANGE = 50.0  # N: the hinge force a bot observes saturates here
BEAM_HINGE_FORCE_LIMIT = 1000.0  # N: what one hinge may apply (pybullet's maxForce)


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
        check_ranges(self, ranges, units)

    def length(self, n_bots: int) -> float:
        """m: the beam of a column of `n_bots`."""
        return (n_bots - 1) * self.spacing + 2 * self.overhang


@register_scenario
class BeamCarry(Column):
    """The column carries one beam (`Beam`), hinged to the top of every torso. Each bot
    observes the force its two hinges exert on it, along the beam and across it
    (square to the beam, in its vertical plane), and the beam's pitch and pitch rate.
    The team's velocity is the beam's, along its length.

    `payload_mass` loads the beam (kg at its centre), not the torsos. `com_offset` does
    not apply: it reloads a torso, and the hinges hold the torso as built."""

    name = "beam-carry"
    summary = "a column of bots carrying one beam hinged to every torso, led by the front bot"
    coupling_type = Beam
    perturbations = ("payload_mass", "friction", "motor_strength", "action_delay", "push")
    units: ClassVar[dict[str, str]] = {"payload_mass": "kg at the beam's centre"}
    pull_forward = "hinge_force_along"
    coupling_layout = (
        ObservationField(
            "hinge_force_along",
            "N",
            -HINGE_FORCE_RANGE,
            HINGE_FORCE_RANGE,
            "the hinges' force on this bot along the beam, + forward",
        ),
        ObservationField(
            "hinge_force_across",
            "N",
            -HINGE_FORCE_RANGE,
            HINGE_FORCE_RANGE,
            "the same, square to the beam in its vertical plane, + up",
        ),
        ObservationField("beam_pitch", "rad", -math.pi / 2, math.pi / 2, "the beam's front end up"),
        ObservationField(
            "beam_pitch_rate", "rad/s", -GYRO_RANGE, GYRO_RANGE, "its rate, + front end rising"
        ),
    )

    @staticmethod
    def coupling_spacing(coupling: Beam) -> float:
        return coupling.spacing

    def build(self, client, bots) -> None:
        super().build(client, bots)
        beam, n = self.coupling, len(bots)
        length = beam.length(n)
        shape = client.createCollisionShape(
            pybullet.GEOM_BOX, halfExtents=(beam.width / 2, length / 2, beam.thickness / 2)
        )
        visual = client.createVisualShape(
            pybullet.GEOM_BOX,
            halfExtents=(beam.width / 2, length / 2, beam.thickness / 2),
            rgbaColor=(0.8, 0.5, 0.2, 1.0),
        )
        self.beam = client.createMultiBody(
            baseMass=beam.mass,
            baseCollisionShapeIndex=shape,
            baseVisualShapeIndex=visual,
            basePosition=PARKED,
        )
        for bot in bots:  # the beam collides with the ground only
            for link in (-1, *range(client.getNumJoints(bot.body))):
                client.setCollisionFilterPair(self.beam, bot.body, -1, link, 0)
        self.hinges = []  # per bot: its two constraints
        self._above_com = above = [model.model.top_above_com for model in self.roster]
        for i, bot in enumerate(bots):
            along = (n - 1) / 2 * beam.spacing - i * beam.spacing  # bot 0 at the front end
            pair = []
            for side in (-beam.hinge_span / 2, beam.hinge_span / 2):
                constraint = client.createConstraint(
                    bot.body,
                    -1,
                    self.beam,
                    -1,
                    pybullet.JOINT_POINT2POINT,
                    (0.0, 0.0, 0.0),
                    (side, 0.0, above[i]),
                    (side, along, -beam.thickness / 2),
                )
                client.changeConstraint(constraint, maxForce=BEAM_HINGE_FORCE_LIMIT)
                pair.append(constraint)
            self.hinges.append(tuple(pair))
        self._placed = False

    def move_clear(self, scene) -> None:
        self._client.resetBasePositionAndOrientation(self.beam, PARKED, (0.0, 0.0, 0.0, 1.0))

    def set_payload(self, scene, kg: float) -> None:
        """`payload_mass`: `kg` more on the beam, at its centre."""
        self._client.changeDynamics(self.beam, -1, mass=self.coupling.mass + kg)

    def place(self, scene, rng) -> None:
        """The beam level on the torsos' tops, along the column."""
        client, tops = self._client, []
        for body, above in zip(self._bodies, self._above_com, strict=True):
            position, orientation = client.getBasePositionAndOrientation(body)
            up = pybullet.getMatrixFromQuaternion(orientation)[2::3]
            tops.append([p + above * u for p, u in zip(position, up, strict=True)])
        centre = np.mean(tops, axis=0)
        centre[2] += self.coupling.thickness / 2
        forward = np.subtract(tops[0], tops[-1])
        yaw = math.atan2(-forward[0], forward[1])
        client.resetBasePositionAndOrientation(
            self.beam, centre.tolist(), pybullet.getQuaternionFromEuler((0.0, 0.0, yaw))
        )
        client.resetBaseVelocity(self.beam, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        # The hinges have held nothing yet: bullet keeps the last episode's force in
        # their state until the first step.
        self._placed = True

    def read(self, states: list[Any]) -> None:
        client_id = self._client_id
        _, orientation = pybullet.getBasePositionAndOrientation(self.beam, client_id)
        velocity, spin = pybullet.getBaseVelocity(self.beam, client_id)
        matrix = pybullet.getMatrixFromQuaternion(orientation)
        right, forward, up = matrix[0::3], matrix[1::3], matrix[2::3]
        self._beam_pitch = math.asin(max(-1.0, min(1.0, forward[2])))
        self._beam_pitch_rate = total(w * r for w, r in zip(spin, right, strict=True))
        horizontal = math.hypot(forward[0], forward[1]) or 1.0
        self._beam_velocity = (velocity[0] * forward[0] + velocity[1] * forward[1]) / horizontal
        if self._placed:  # at reset
            self._placed = False
            self._forces = [(0.0, 0.0)] * len(self.hinges)
            return
        forces = []
        for pair in self.hinges:  # the state is the force on the beam: the bot feels minus it
            fx, fy, fz = (0.0, 0.0, 0.0)
            for constraint in pair:
                x, y, z = pybullet.getConstraintState(constraint, client_id)
                fx, fy, fz = fx - x, fy - y, fz - z
            forces.append(
                (
                    fx * forward[0] + fy * forward[1] + fz * forward[2],
                    fx * up[0] + fy * up[1] + fz * up[2],
                )
            )
        self._forces = forces

    def coupling_terms(self, index: int) -> list[float]:
        along, across = self._forces[index]
        top = HINGE_FORCE_RANGE
        return [
            min(max(along, -top), top),
            min(max(across, -top), top),
            self._beam_pitch,
            min(max(self._beam_pitch_rate, -GYRO_RANGE), GYRO_RANGE),
        ]

    def team_velocity(self, states: list[Any]) -> float:
        return self._beam_velocity


# The tasks it plays: each row states all it sets (`TaskSpec`'s defaults for the rest).
_BEAM_TABLE = """\
| beam | value |
|---|---|
| mass | 1.5 kg |
| length | (N - 1) x 0.6 m + 2 x 0.1 m (1.4 m for 3 bots) |
| cross-section | 0.3 m across (along the axles) x 0.04 m high |
| spacing | 0.6 m between neighbouring bots' hinges |
| hinges | per bot, two point-to-point constraints 0.2 m apart on its torso's top: a hinge |
| collisions | the ground only, not the bots |
| target range | [-2, 2] m/s, each held 2-5 s |

`payload_mass` loads the beam (kg at its centre); `com_offset` does not apply."""

TASKS = (
    TaskSpec(
        id="bbbench/BeamCarry-v0",
        summary="a team of 3 bots (2-4) carrying one beam, led by the front bot, at [-2, 2] m/s",
        description=team_description(
            f"""\
A column of bots (3 by default, `n_bots` 2-4) on one heading, 0.6 m apart, carries one
beam hinged to the top of every torso (`BeamCarry`, `Beam`) on flat ground. The team's
velocity is the beam's, along its length. Each bot observes the force its hinges exert on
it along the beam and square to it, and the beam's pitch and pitch rate.

{_BEAM_TABLE}"""
        ),
        reward=StayUpReward(),
        group=Group(n_bots=3),
        command=TEAM_TARGETS,
        scenario="beam-carry",
        coupling=Beam(),
        version_history=TEAM_HISTORY,
        random_return=1.9037218152528517,
    ),
    TaskSpec(
        id="bbbench/BeamCarryBumps-v0",
        summary="BeamCarry's team and beam over smooth random hills (`difficulty=` 0..1)",
        description=team_description(
            f"""\
BeamCarry's team, beam and targets on a 4 x 36 m strip of smooth random hills (Bumps'
generator: white noise low-passed by a Gaussian of 0.35 m, on 0.2 m cells), a new one
from each episode's seed, with flat ground around it. The column starts centred on a
level disc of 1.2 m radius in the strip's middle, so that it can drive 18 m either way.
`difficulty` (default 0.6, any number in [0, 1]) sets the hills' height, 0.02 m + 0.10 m
x difficulty (0.08 m at the default, as high as Bumps-v0's at difficulty 1). On a hill the
beam pitches: the hinges' force along it carries part of its weight.

{_BEAM_TABLE}"""
        ),
        reward=StayUpReward(),
        group=Group(n_bots=3),
        command=TEAM_TARGETS,
        scenario="beam-carry",
        coupling=Beam(),
        terrain=HeightfieldTerrain(
            generator=Bumps(extra_height=0.10),
            difficulty=0.6,
            size=(4.0, 36.0),
            start_margin=18.0,
            start_pad=1.2,
        ),
        version_history=TEAM_HISTORY,
        random_return=1.9029908268947455,
    ),
)

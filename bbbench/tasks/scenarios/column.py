"""Teams in a column, coupled and led: `BeamCarry` (bots carrying one beam) and `Convoy`
(bots tethered each to the next). Only the front bot observes the team's target; the
team earns one reward and a fall ends it (multiwalker's `terminate_on_fall`)."""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
import pybullet
from gymnasium import spaces

from bbbench.portable import dot3
from bbbench.robots.layout import GYRO_RANGE, OBSERVATION_DTYPE, ObservationField
from bbbench.tasks.coupling import MAX_TEAM, Beam, Tether
from bbbench.tasks.group import NEIGHBOUR_SPEED_RANGE
from bbbench.tasks.reward import has_fallen
from bbbench.tasks.scenarios.base import Outcome, Pose, Scenario, Slots, fell_cause

NEIGHBOUR_REACH = 5.0  # m: offsets to a neighbour saturate here
HINGE_FORCE_RANGE = 50.0  # N: the hinge force a bot observes saturates here
STRETCH_RANGE = 5.0  # m
STRETCH_RATE_RANGE = 10.0  # m/s
BEAM_HINGE_FORCE_LIMIT = 1000.0  # N: what one hinge may apply (pybullet's maxForce)
_PARKED = (0.0, -2000.0, 20.0)  # m: where a coupling's body waits between episodes
_BEADS_PER_TETHER = 12  # what a frame shows of a tether


def _neighbour_fields(where: str) -> tuple[ObservationField, ...]:
    reach, top = NEIGHBOUR_REACH, NEIGHBOUR_SPEED_RANGE
    return (
        ObservationField(f"{where}_present", "", 0.0, 1.0, f"1 if there is a bot {where}, else 0"),
        ObservationField(f"{where}_right", "m", -reach, reach, f"the bot {where}: to the right"),
        ObservationField(f"{where}_forward", "m", -reach, reach, "its distance ahead"),
        ObservationField(
            f"{where}_right_velocity", "m/s", -top, top, "its velocity minus this bot's, right"
        ),
        ObservationField(f"{where}_forward_velocity", "m/s", -top, top, "the same, ahead"),
    )


NEIGHBOUR_LAYOUT = _neighbour_fields("ahead") + _neighbour_fields("behind")


class Column(Scenario):
    """N bots (2 to 4) in a column on one heading, coupled by the task's `coupling`.

    The column is centred on the origin, heading along +y: bot 0 at the front, bot i
    i x spacing behind it (so a start pad about the origin holds the whole team). All
    lean by one pitch drawn from U(-initial_pitch, initial_pitch), so that the coupling
    starts at rest. The team follows one target schedule; only the
    front bot observes it (the others read 0 in the target slot) and must infer it
    from the coupling and from their neighbours.

    Team reward, the shared reward's form (`StayUpReward.terms`), the same for every
    agent: upright from the most tilted bot's pitch, tracking from the team's velocity
    (`team_velocity`) against the target. A fall of any bot, or the coupling's own end
    (`broken`), terminates every agent.
    """

    multi_agent = True
    team = True
    robots: ClassVar[tuple[str, ...] | None] = ("two-wheel",)  # the hinges hold its torso
    most_bots = MAX_TEAM
    coupling_type: ClassVar[type]
    coupling_layout: ClassVar[tuple[ObservationField, ...]]
    # The coupling's value that reads its pull forward on a bot (what a follower's law
    # may add to the speed of the bot ahead): a field of `coupling_layout`.
    pull_forward: ClassVar[str]

    def __init__(self, task) -> None:
        super().__init__(task)
        self.coupling = task.coupling
        self.spacing = self.coupling_spacing(task.coupling)
        own = self.robot.layout()
        fields = own + self.coupling_layout + NEIGHBOUR_LAYOUT
        self._space = spaces.Box(
            low=np.array([f.low for f in fields], dtype=OBSERVATION_DTYPE),
            high=np.array([f.high for f in fields], dtype=OBSERVATION_DTYPE),
            dtype=OBSERVATION_DTYPE,
        )
        self.layout = fields
        self._bodies: tuple[int, ...] = ()
        self._client_id = -1

    @staticmethod
    def coupling_spacing(coupling: Any) -> float:
        raise NotImplementedError

    @classmethod
    def refusal(cls, task) -> str | None:
        refused = super().refusal(task)
        if refused:
            return refused
        if not isinstance(task.coupling, cls.coupling_type):
            return (
                f"{task.id}: the {cls.name!r} scenario needs a {cls.coupling_type.__name__} "
                f"coupling (bbbench.tasks.coupling), got {task.coupling!r}"
            )
        return None

    # -- the world and the start ----------------------------------------------------

    def build(self, client, bots) -> None:
        self._client = client
        self._client_id = bots[0].client_id
        self._bodies = tuple(bot.body for bot in bots)

    def starts(self, rng: np.random.Generator) -> tuple[list[Pose], list[float]]:
        pitch = float(rng.uniform(-self.task.initial_pitch, self.task.initial_pitch))
        n = self.n_bots
        front = (n - 1) / 2 * self.spacing
        return [((0.0, front - self.spacing * i), 0.0) for i in range(n)], [pitch] * n

    def targets(self, rng: np.random.Generator) -> list[list[float]]:
        task = self.task
        row = task.command.targets(rng, task.max_episode_steps, task.control_dt)
        return [row] * self.n_bots  # one schedule: the team's

    # -- observations ----------------------------------------------------------------

    def observation_space(self) -> spaces.Box:
        return self._space

    def slots(self) -> Slots:
        """The robot's own values and the coupling's, then the bots ahead and behind,
        each slot led by its presence bit."""
        width = len(NEIGHBOUR_LAYOUT) // 2
        return Slots(len(self.layout) - 2 * width, 2, width, 0)

    def observe(
        self, scene: Any, states: list[Any], commands: list[float], targets: list[float], step: int
    ) -> np.ndarray:
        """Each bot's row: its robot's values (the front bot's target; 0 for the others),
        what it observes of the coupling, and its neighbours ahead and behind."""
        self.read(states)
        values = self.robot.values
        n = len(states)
        rows = []
        for i, state in enumerate(states):
            reading = (state.pitch, state.pitch_rate, state.wheel_speed)
            row = [*values(reading, commands[i], targets[i] if i == 0 else 0.0, state)]
            row += self.coupling_terms(i)
            row += _neighbour(state, states[i - 1]) if i > 0 else _ABSENT
            row += _neighbour(state, states[i + 1]) if i + 1 < n else _ABSENT
            rows.append(row)
        return np.array(rows, dtype=OBSERVATION_DTYPE)

    def read(self, states: list[Any]) -> None:
        """Read the coupling once, after each reset and step (before `outcome`)."""
        raise NotImplementedError

    def coupling_terms(self, index: int) -> list[float]:
        """What bot `index` observes of the coupling (`coupling_layout`), from `read`."""
        raise NotImplementedError

    # -- the team's outcome ---------------------------------------------------------

    def team_velocity(self, states: list[Any]) -> float:
        """The team's forward velocity (m/s), scored against the target."""
        raise NotImplementedError

    def broken(self) -> bool:
        """Whether the coupling itself ended the episode (from `read`)."""
        return False

    broken_cause: ClassVar[str] = "the coupling broke"  # an Outcome's cause when it does

    def outcome(
        self, agents: list[str], states: list[Any], targets: list[float], seed: int
    ) -> Outcome:
        """The team's reward, computed once, for every bot; the episode is over for all
        of them at a fall of any bot or when the coupling breaks, and the cause names
        the bots that fell and a broken coupling."""
        pitch = max((state.pitch for state in states), key=abs)
        velocity_error = abs(self.team_velocity(states) - targets[0])
        upright, velocity = self.reward.terms(pitch, velocity_error)
        fell = [has_fallen(state) for state in states]
        broken = self.broken()
        cause = "; ".join(
            [c for c in (fell_cause(agents, fell), self.broken_cause if broken else "") if c]
        )
        info = {
            "reward_upright": upright,
            "reward_velocity": velocity,
            "velocity_error": velocity_error,
            "episode_seed": seed,
        }
        return Outcome(
            [upright + velocity] * len(agents),
            fell,
            broken or any(fell),
            cause,
            [dict(info) for _ in agents],
        )


_ABSENT = [0.0] * 5


def _neighbour(state: Any, other: Any) -> list[float]:
    """[present, right, forward, right velocity, forward velocity] of `other` in the frame
    of `state`'s bot (between torso centres, horizontally; axle velocities), saturated."""
    forward_x, forward_y = state.heading
    turn = complex(forward_y, forward_x)  # i * conj(heading): world -> right + i ahead
    offset = complex(other.position[0] - state.position[0], other.position[1] - state.position[1])
    offset *= turn
    moving = (complex(*other.velocity) - complex(*state.velocity)) * turn
    reach, top = NEIGHBOUR_REACH, NEIGHBOUR_SPEED_RANGE
    return [
        1.0,
        min(max(offset.real, -reach), reach),
        min(max(offset.imag, -reach), reach),
        min(max(moving.real, -top), top),
        min(max(moving.imag, -top), top),
    ]


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
            basePosition=_PARKED,
        )
        for bot in bots:  # the beam collides with the ground only
            for link in (-1, *range(client.getNumJoints(bot.body))):
                client.setCollisionFilterPair(self.beam, bot.body, -1, link, 0)
        model = self.robot.model
        above_com = model.torso_top_height - model.torso_com_height
        self.hinges = []  # per bot: its two constraints
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
                    (side, 0.0, above_com),
                    (side, along, -beam.thickness / 2),
                )
                client.changeConstraint(constraint, maxForce=BEAM_HINGE_FORCE_LIMIT)
                pair.append(constraint)
            self.hinges.append(tuple(pair))
        self._above_com = above_com
        self._placed = False

    def move_clear(self, scene) -> None:
        self._client.resetBasePositionAndOrientation(self.beam, _PARKED, (0.0, 0.0, 0.0, 1.0))

    def set_payload(self, scene, kg: float) -> None:
        """`payload_mass`: `kg` more on the beam, at its centre."""
        self._client.changeDynamics(self.beam, -1, mass=self.coupling.mass + kg)

    def place(self, scene, rng) -> None:
        """The beam level on the torsos' tops, along the column."""
        client, tops = self._client, []
        for body in self._bodies:
            position, orientation = client.getBasePositionAndOrientation(body)
            up = pybullet.getMatrixFromQuaternion(orientation)[2::3]
            tops.append([p + self._above_com * u for p, u in zip(position, up, strict=True)])
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
        self._beam_pitch_rate = sum(w * r for w, r in zip(spin, right, strict=True))
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
                [client.createMultiBody(0.0, -1, bead, _PARKED) for _ in range(_BEADS_PER_TETHER)]
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
        return sum(state.forward_velocity for state in states) / len(states)

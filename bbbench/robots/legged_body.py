"""The wheel-legged robot's body: its facts read from `wheel_legged.urdf` (`LEGGED_MODEL`),
its state (`LeggedState`) and `WheelLeggedBot`, one body in a world with its leg servos
and wheel motors. `bbbench.robots.wheel_legged` is its face to its tasks (actions and
observation layout) and documents the robot."""

from __future__ import annotations

import collections
import functools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import pybullet
from pybullet_utils.bullet_client import BulletClient

from bbbench.portable import total
from bbbench.robots.balancebot import tilt_from_quaternion
from bbbench.robots.body import Body, WheeledModel, rolling_radius, urdf_parts

URDF_PATH = Path(__file__).with_name("wheel_legged.urdf")

LEG_JOINT_NAMES = ("left_hip", "left_knee", "right_hip", "right_knee")
WHEEL_JOINT_NAMES = ("left_wheel_joint", "right_wheel_joint")
# 1/s: a leg servo asks for this many rad/s per rad of error, a time constant of 0.2 s.
# The servos are soft on purpose, like a suspension: a leg's reaction moves the light
# torso (0.002 kg m^2 about the axle), and stiff legs shook it off balance whenever their
# targets jittered, as a learning policy's do. Measured with the PD wheels holding the
# robot on flat ground and Gaussian noise on the four leg actions, mean episode length of
# 10 (of 1500 steps) at noise 0.1 / 0.3: gain 20 and 3 N m, 511 / 80; gain 20 and 1.5 N m,
# 1183 / 177; gain 5 and 1.5 N m, 1500 / 1421. PPO (300k steps) learnt to stand with the
# last; with the first it fell in every episode.
LEG_POSITION_GAIN = 5.0
# The largest change of one wheel's commanded speed per step, rad/s: the two-wheel bot's.
MAX_WHEEL_SPEED_CHANGE = 1.0


@dataclass(frozen=True)
class LegJoint:
    """One leg joint's servo, as its URDF `<limit>` says."""

    name: str
    lower: float  # rad
    upper: float  # rad
    effort: float  # N m
    velocity: float  # rad/s

    @property
    def centre(self) -> float:
        return 0.5 * (self.lower + self.upper)

    @property
    def half_range(self) -> float:
        return 0.5 * (self.upper - self.lower)


@dataclass(frozen=True)
class LeggedModel(WheeledModel):
    """The wheel-legged robot's facts, read from its URDF (the one place they are written)."""

    urdf_path: Path
    legs: tuple[LegJoint, ...]  # LEG_JOINT_NAMES' joints, in that order
    thigh_length: float  # m, hip to knee
    shin_length: float  # m, knee to axle
    hip_below_centre: float  # m, hips below the torso's centre
    wheel_offset: float  # m, each wheel's centre from the centre line (x)
    wheel_radius: float  # m
    wheel_speed_limit: float  # rad/s
    motor_torque_limit: float  # N m per wheel
    torso_size: tuple[float, float, float]  # m, the torso box (x across, y forward, z up)
    torso_mass: float  # kg
    wheel_mass: float  # kg, each
    mass: float  # kg, the whole robot

    @property
    def top_above_com(self) -> float:
        """m: the top of the torso above its centre of mass (where a beam is hinged); the
        URDF puts the torso's centre of mass at the centre of its box."""
        return self.torso_size[2] / 2

    @property
    def standing(self) -> tuple[float, ...]:
        """The leg angles at rest (rad, LEG_JOINT_NAMES' order): the centre of each range."""
        return tuple(leg.centre for leg in self.legs)

    def axle_below_hip(self, hip: float, knee: float) -> float:
        """How far (m) the axle is below the hip at these joint angles, along the torso."""
        return self.thigh_length * math.cos(hip) + self.shin_length * math.cos(hip + knee)

    def axle_ahead_of_hip(self, hip: float, knee: float) -> float:
        """How far (m) the axle is ahead of the hip at these joint angles, along the torso."""
        return self.thigh_length * math.sin(hip) + self.shin_length * math.sin(hip + knee)


def read_legged_model(urdf_path: Path = URDF_PATH) -> LeggedModel:
    """Parse the wheel-legged robot's facts out of its URDF."""
    joints, links = urdf_parts(urdf_path)

    def xyz(element) -> list[float]:
        return [float(value) for value in element.find("origin").get("xyz").split()]

    def limit(name: str, key: str) -> float:
        return float(joints[name].find("limit").get(key))

    legs = tuple(
        LegJoint(
            name,
            limit(name, "lower"),
            limit(name, "upper"),
            limit(name, "effort"),
            limit(name, "velocity"),
        )
        for name in LEG_JOINT_NAMES
    )
    wheel = joints["left_wheel_joint"]
    hip = joints["left_hip"]
    masses = [float(link.find("inertial/mass").get("value")) for link in links.values()]
    return LeggedModel(
        urdf_path=urdf_path,
        legs=legs,
        thigh_length=-xyz(joints["left_knee"])[2],
        shin_length=-xyz(wheel)[2],
        hip_below_centre=-xyz(hip)[2],
        wheel_offset=abs(xyz(hip)[0] + xyz(wheel)[0]),
        wheel_radius=rolling_radius(links, wheel),
        wheel_speed_limit=limit("left_wheel_joint", "velocity"),
        motor_torque_limit=limit("left_wheel_joint", "effort"),
        torso_size=tuple(
            float(x) for x in links["torso"].find("collision/geometry/box").get("size").split()
        ),
        torso_mass=float(links["torso"].find("inertial/mass").get("value")),
        wheel_mass=float(links["left_wheel"].find("inertial/mass").get("value")),
        mass=total(masses),
    )


LEGGED_MODEL = read_legged_model()


def facts_markdown(model: LeggedModel = LEGGED_MODEL) -> str:
    """The robot's facts as a Markdown table, from its URDF: the module's docstring and
    docs/robots.md carry it (tests/test_wheel_legged.py checks both)."""
    (hip, knee), wheel = model.legs[:2], model.wheel_radius
    standing_hip = hip.centre
    rows = [
        (
            "torso",
            f"box {' x '.join(f'{x:g}' for x in model.torso_size)} m, {model.torso_mass:g} kg",
        ),
        ("thigh, shin", f"{model.thigh_length:g} m and {model.shin_length:g} m"),
        ("wheels", f"radius {wheel:g} m, {model.wheel_offset:g} m either side of the centre"),
        ("total mass", f"{model.mass:g} kg"),
        ("hip range", f"{hip.lower:g} to {hip.upper:g} rad (+: thigh forward)"),
        ("knee range", f"{knee.lower:g} to {knee.upper:g} rad (-: shin backward)"),
        ("leg servos", f"{hip.effort:g} N m, {hip.velocity:g} rad/s"),
        (
            "wheel motors",
            f"{model.motor_torque_limit:g} N m, {model.wheel_speed_limit:g} rad/s "
            f"({model.top_speed:.2f} m/s)",
        ),
        ("standing pose", f"hip {standing_hip:g} rad, knee {knee.centre:g} rad"),
        (
            "axle below the hips",
            f"{model.axle_below_hip(-knee.lower / 2, knee.lower):.3f} to "
            f"{model.axle_below_hip(0.0, 0.0):.3f} m with knee = -2 hip; "
            f"{model.axle_below_hip(standing_hip, knee.centre):.3f} m standing",
        ),
    ]
    return "\n".join(["| part | value |", "|---|---|", *(f"| {a} | {b} |" for a, b in rows)])


class LeggedState(NamedTuple):
    """One reading of the wheel-legged robot: `BotState`'s fields, then the legs'.
    Angles in rad, rates in rad/s, velocities in m/s, lengths in m."""

    position: tuple[float, float, float]  # the torso's centre of mass, world frame
    orientation: tuple[float, float, float, float]  # torso quaternion (x, y, z, w)
    pitch: float
    pitch_rate: float
    tilt: float
    wheel_speed: float  # the mean of the two, relative to their shins
    forward_velocity: float
    velocity: tuple[float, float]  # the axle midpoint's horizontal velocity, world frame
    heading: tuple[float, float]
    axle: tuple[float, float, float]  # the axle midpoint, world frame
    leg_angles: tuple[float, float, float, float]  # LEG_JOINT_NAMES' order
    leg_rates: tuple[float, float, float, float]
    wheel_speeds: tuple[float, float]  # (left, right)
    wheel_commands: tuple[float, float]  # (left, right): the speeds asked of the wheels
    roll: float  # lean towards the right side (+x)
    roll_rate: float
    height: float  # the torso's centre above the axle midpoint, m (vertical)


_new_state = functools.partial(tuple.__new__, LeggedState)


def legged_spawn_pose(
    pitch: float,
    yaw: float,
    xy: tuple[float, float],
    ground_height: float,
    model: LeggedModel = LEGGED_MODEL,
    com_forward: float = 0.0,
) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
    """The torso's centre of mass and orientation with the legs standing and the wheels on
    the ground at `xy`, the whole robot leaning by `pitch` rad about the axle."""
    hip, knee = model.standing[:2]
    below = model.hip_below_centre + model.axle_below_hip(hip, knee)
    ahead = model.axle_ahead_of_hip(hip, knee)
    orientation = pybullet.getQuaternionFromEuler((-pitch, 0.0, yaw))
    matrix = pybullet.getMatrixFromQuaternion(orientation)
    up, forward = matrix[2::3], matrix[1::3]  # body z and y axes in world
    axle = (xy[0], xy[1], ground_height + model.wheel_radius)
    # The centre is `below` above the axle and `ahead` behind it, along the torso.
    centre = tuple(
        a + below * u + (com_forward - ahead) * f for a, u, f in zip(axle, up, forward, strict=True)
    )
    return centre, orientation


class WheelLeggedBot(Body):
    """One wheel-legged robot in a bullet world (`bbbench.robots.wheel_legged`).

    `act((hip_l, knee_l, hip_r, knee_r, change_l, change_r))` sets the leg targets (rad,
    clipped to the joints' ranges) and changes each wheel's commanded speed (rad/s,
    clamped to the wheel-speed limit), and returns the mean wheel command.
    """

    def __init__(self, client: BulletClient, model: LeggedModel = LEGGED_MODEL) -> None:
        self.model = model
        super().__init__(client, model.urdf_path, WHEEL_JOINT_NAMES)
        self._ranges = tuple((leg.lower, leg.upper) for leg in model.legs)
        self._leg_speed_limits = tuple(leg.velocity for leg in model.legs)
        self.set_motor_strength(1.0)
        self._delayed: collections.deque | None = None  # (targets, commands) not yet sent
        self.leg_targets = model.standing
        self.wheel_commands = (0.0, 0.0)
        self.wheel_command = 0.0  # the mean of the two, rad/s
        self._actuate()

    def _load(self, urdf_path: str) -> int:
        body = super()._load(urdf_path)
        self.leg_joints = tuple(self.joint_index[name] for name in LEG_JOINT_NAMES)
        self._joints = (*self.leg_joints, *self.wheel_joints)
        return body

    # -- acting ---------------------------------------------------------------

    def set_motor_strength(self, factor: float) -> None:
        """Servos (legs and wheels) `factor` times as strong as the URDF's limits say."""
        wheel = self.model.motor_torque_limit * factor
        self._forces = (*(leg.effort * factor for leg in self.model.legs), wheel, wheel)

    def set_action_delay(self, steps: int) -> None:
        """Send each action to the servos `steps` actions later (0: at once); until then
        they hold the standing pose and 0 rad/s."""
        self._delayed = collections.deque([self._rest()] * steps) if steps else None

    def _rest(self) -> tuple[tuple[float, ...], tuple[float, float]]:
        return self.model.standing, (0.0, 0.0)

    def act(self, decoded: tuple[float, ...]) -> float:
        """Set the leg targets (rad; clipped to the joints' ranges) and change the wheels'
        commanded speeds (rad/s; clamped to the limit): `decoded` is the four targets
        then the two changes. NaN raises ValueError.

        Written out, value by value: it runs every step (benchmarks/bench_robots.py)."""
        t0, t1, t2, t3, change_left, change_right = decoded
        if not (t0 == t0 and t1 == t1 and t2 == t2 and t3 == t3):
            raise ValueError("a leg target is NaN; expected numbers of rad")
        (lo0, hi0), (lo1, hi1), (lo2, hi2), (lo3, hi3) = self._ranges
        self.leg_targets = (
            hi0 if t0 > hi0 else lo0 if t0 < lo0 else t0,
            hi1 if t1 > hi1 else lo1 if t1 < lo1 else t1,
            hi2 if t2 > hi2 else lo2 if t2 < lo2 else t2,
            hi3 if t3 > hi3 else lo3 if t3 < lo3 else t3,
        )
        top = self.model.wheel_speed_limit
        left, right = self.wheel_commands
        left += change_left
        right += change_right
        if not (left == left and right == right):
            raise ValueError("a wheel change is NaN; expected numbers of rad/s")
        left = top if left > top else -top if left < -top else left
        right = top if right > top else -top if right < -top else right
        self.wheel_commands = (left, right)
        self.wheel_command = 0.5 * (left + right)
        self._actuate()
        return self.wheel_command

    def _actuate(self) -> None:
        targets, commands = self.leg_targets, self.wheel_commands
        if self._delayed is not None:
            self._delayed.append((targets, commands))
            targets, commands = self._delayed.popleft()
        self._drive(targets, commands)

    def _stop(self) -> None:
        self.leg_targets, self.wheel_commands, self.wheel_command = self.model.standing, (0, 0), 0
        self._drive(*self._rest())

    def _drive(self, targets: tuple[float, ...], commands: tuple[float, float]) -> None:
        """Ask each leg servo for the speed towards its target from its angle now, and the
        wheels for theirs."""
        body, client_id = self.body, self._client_id
        (a0, *_), (a1, *_), (a2, *_), (a3, *_) = pybullet.getJointStates(
            body, self.leg_joints, client_id
        )
        t0, t1, t2, t3 = targets
        g = LEG_POSITION_GAIN
        v0, v1, v2, v3 = g * (t0 - a0), g * (t1 - a1), g * (t2 - a2), g * (t3 - a3)
        s0, s1, s2, s3 = self._leg_speed_limits
        pybullet.setJointMotorControlArray(
            body,
            self._joints,
            pybullet.VELOCITY_CONTROL,
            targetVelocities=(
                s0 if v0 > s0 else -s0 if v0 < -s0 else v0,
                s1 if v1 > s1 else -s1 if v1 < -s1 else v1,
                s2 if v2 > s2 else -s2 if v2 < -s2 else v2,
                s3 if v3 > s3 else -s3 if v3 < -s3 else v3,
                *commands,
            ),
            forces=self._forces,
            physicsClientId=client_id,
        )

    # `reset` (Body's): standing, the legs at the centres of their ranges.
    def _spawn_pose(self, pitch, yaw, xy, ground_height):
        return legged_spawn_pose(pitch, yaw, xy, ground_height, self.model, self._com_forward)

    def _joints_at_rest(self) -> list[tuple[int, float]]:
        legs = list(zip(self.leg_joints, self.model.standing, strict=True))
        return legs + super()._joints_at_rest()

    def _hold_still(self) -> None:
        if self._delayed is not None:
            self._delayed = collections.deque([self._rest()] * len(self._delayed))
        self.leg_targets, self.wheel_commands, self.wheel_command = self.model.standing, (0, 0), 0
        self._actuate()

    # -- sensing --------------------------------------------------------------

    def read(self) -> LeggedState:
        """Query the world once and return the robot's state in its own frame."""
        body, client_id = self.body, self._client_id
        position, orientation = pybullet.getBasePositionAndOrientation(body, client_id)
        _, (wx, wy, wz) = pybullet.getBaseVelocity(body, client_id)
        joints = pybullet.getJointStates(body, self._joints, client_id)
        left, right = pybullet.getLinkStates(
            body, self.wheel_joints, computeLinkVelocity=1, physicsClientId=client_id
        )
        r00, r01, _, r10, r11, _, r20, r21, r22 = pybullet.getMatrixFromQuaternion(orientation)
        (lx, ly, lz), (rx, ry, rz) = left[0], right[0]
        axle = (0.5 * (lx + rx), 0.5 * (ly + ry), 0.5 * (lz + rz))
        vx = 0.5 * (left[6][0] + right[6][0])
        vy = 0.5 * (left[6][1] + right[6][1])
        e = self._com_forward
        if e:  # `set_com_offset`: report the torso's centre as built
            px, py, pz = position
            position = (px - e * r01, py - e * r11, pz - e * r21)
        length = math.hypot(r01, r11)
        heading = (r01 / length, r11 / length) if length > 1e-9 else (0.0, 1.0)
        (a0, r0, *_), (a1, r1, *_), (a2, r2, *_), (a3, r3, *_) = joints[:4]
        angles = (a0, a1, a2, a3)
        wheel_left, wheel_right = joints[4][1], joints[5][1]
        return _new_state(
            (
                position,
                orientation,
                math.atan2(-r21, r22),  # pitch
                0.0 - (r00 * wx + r10 * wy + r20 * wz),  # pitch rate
                tilt_from_quaternion(orientation),
                0.5 * (wheel_left + wheel_right),
                vx * heading[0] + vy * heading[1],
                (vx, vy),
                heading,
                axle,
                angles,
                (r0, r1, r2, r3),
                (wheel_left, wheel_right),
                self.wheel_commands,
                math.atan2(-r20, r22),  # roll
                r01 * wx + r11 * wy + r21 * wz,  # roll rate
                position[2] - axle[2],
            )
        )

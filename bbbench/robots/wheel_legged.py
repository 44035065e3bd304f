"""The wheel-legged balancer: a torso on two legs, each with a hip, a knee and a wheel.

The tutorial's third idea (a robot like Boston Dynamics' Handle), in the two-wheel
bot's family: the same 0.1 m wheels and wheel motors, the same shared observation
first, the same tasks and ground. The legs set the torso's height and can level it
over uneven ground; the wheels balance it. Upkie and Ascento are the real robots of
this kind.

Facts, read from `wheel_legged.urdf` (`read_legged_model`; tests/test_wheel_legged.py
checks this table against the file):

| part | value |
|---|---|
| torso | box 0.2 x 0.08 x 0.16 m, 0.8 kg |
| thigh, shin | 0.15 m and 0.15 m |
| wheels | radius 0.1 m, 0.13 m either side of the centre |
| total mass | 1.2 kg |
| hip range | -0.4 to 1.6 rad (+: thigh forward) |
| knee range | -2.4 to 0 rad (-: shin backward) |
| leg servos | 3 N m, 8 rad/s |
| wheel motors | 0.6 N m, 24.6 rad/s (2.46 m/s) |
| standing pose | hip 0.6 rad, knee -1.2 rad |
| axle below the hips | 0.109 to 0.300 m with knee = -2 hip; 0.248 m standing |

Conventions are the two-wheel bot's (`bbbench.robots.balancebot`): forward is +y, pitch
leans forward, wheel speed is the mean of the two wheels relative to their shins
(encoders), forward velocity is the axle midpoint's true horizontal velocity along the
heading. Roll is the torso's lean towards its right side (+x), in rad.

Leg servos are position loops: each control step the servo is asked for the joint
speed `LEG_POSITION_GAIN * (target - angle)`, clipped to the joint's speed limit, and
holds it with at most the joint's torque limit. Targets are clipped to the joint's
range, so no target outside it reaches a servo.
"""

from __future__ import annotations

import collections
import functools
import math
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pybullet
from gymnasium import spaces
from pybullet_utils.bullet_client import BulletClient

from bbbench.robots.balancebot import tilt_from_quaternion
from bbbench.robots.body import Body
from bbbench.robots.layout import (
    ENCODER_SPEED_RANGE,
    GYRO_RANGE,
    OBSERVATION_DTYPE,
    ObservationField,
    clipped_scan,
    sensed,
    shared_layout,
)
from bbbench.robots.robot import Robot

URDF_PATH = Path(__file__).with_name("wheel_legged.urdf")

LEG_JOINT_NAMES = ("left_hip", "left_knee", "right_hip", "right_knee")
WHEEL_JOINT_NAMES = ("left_wheel_joint", "right_wheel_joint")
# 1/s: a leg servo asks for this many rad/s per rad of error (a time constant of 50 ms,
# five control steps: fast against the balance, slow enough for one step per update).
LEG_POSITION_GAIN = 20.0
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
class LeggedModel:
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
    def standing(self) -> tuple[float, ...]:
        """The leg angles at rest (rad, LEG_JOINT_NAMES' order): the centre of each range."""
        return tuple(leg.centre for leg in self.legs)

    def axle_below_hip(self, hip: float, knee: float) -> float:
        """How far (m) the axle is below the hip at these joint angles, along the torso."""
        return self.thigh_length * math.cos(hip) + self.shin_length * math.cos(hip + knee)

    def axle_ahead_of_hip(self, hip: float, knee: float) -> float:
        """How far (m) the axle is ahead of the hip at these joint angles, along the torso."""
        return self.thigh_length * math.sin(hip) + self.shin_length * math.sin(hip + knee)

    @property
    def top_speed(self) -> float:
        return self.wheel_speed_limit * self.wheel_radius


def read_legged_model(urdf_path: Path = URDF_PATH) -> LeggedModel:
    """Parse the wheel-legged robot's facts out of its URDF."""
    robot = ET.parse(urdf_path).getroot()
    joints = {joint.get("name"): joint for joint in robot.iter("joint")}
    links = {link.get("name"): link for link in robot.iter("link")}

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
        wheel_radius=float(
            links[wheel.find("child").get("link")]
            .find("collision/geometry/*[@radius]")
            .get("radius")
        ),
        wheel_speed_limit=limit("left_wheel_joint", "velocity"),
        motor_torque_limit=limit("left_wheel_joint", "effort"),
        torso_size=tuple(
            float(x) for x in links["torso"].find("collision/geometry/box").get("size").split()
        ),
        torso_mass=float(links["torso"].find("inertial/mass").get("value")),
        wheel_mass=float(links["left_wheel"].find("inertial/mass").get("value")),
        mass=sum(masses),
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
        self._strength = 1.0
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
        self._strength = factor

    def set_action_delay(self, steps: int) -> None:
        """Send each action to the servos `steps` actions later (0: at once); until then
        they hold the standing pose and 0 rad/s."""
        self._delayed = collections.deque([self._rest()] * steps) if steps else None

    def _rest(self) -> tuple[tuple[float, ...], tuple[float, float]]:
        return self.model.standing, (0.0, 0.0)

    def act(self, decoded: tuple[float, ...]) -> float:
        """Set the leg targets (rad; clipped to the joints' ranges) and change the wheels'
        commanded speeds (rad/s; clamped to the limit): `decoded` is the four targets
        then the two changes. NaN raises ValueError."""
        legs = self.model.legs
        targets = tuple(
            leg.upper if value > leg.upper else leg.lower if value < leg.lower else value
            for leg, value in zip(legs, decoded[:4], strict=True)
        )
        limit = self.model.wheel_speed_limit
        commands = tuple(
            min(limit, max(-limit, command + change))
            for command, change in zip(self.wheel_commands, decoded[4:], strict=True)
        )
        if any(value != value for value in (*targets, *commands)):
            raise ValueError("a leg target or wheel change is NaN; expected numbers")
        self.leg_targets, self.wheel_commands = targets, commands
        self.wheel_command = 0.5 * (commands[0] + commands[1])
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
        """Ask each leg servo for the speed towards its target, and the wheels for theirs."""
        client_id, body = self._client_id, self.body
        angles = pybullet.getJointStates(body, self.leg_joints, client_id)
        strength = self._strength
        speeds, forces = [], []
        for leg, target, (angle, *_) in zip(self.model.legs, targets, angles, strict=True):
            speed = LEG_POSITION_GAIN * (target - angle)
            top = leg.velocity
            speeds.append(top if speed > top else -top if speed < -top else speed)
            forces.append(leg.effort * strength)
        wheel_force = self.model.motor_torque_limit * strength
        pybullet.setJointMotorControlArray(
            body,
            self._joints,
            pybullet.VELOCITY_CONTROL,
            targetVelocities=(*speeds, *commands),
            forces=(*forces, wheel_force, wheel_force),
            physicsClientId=client_id,
        )

    def reset(
        self,
        pitch: float = 0.0,
        yaw: float = 0.0,
        xy: tuple[float, float] = (0.0, 0.0),
        ground_height: float = 0.0,
        drop_contacts: bool = True,
    ) -> None:
        """Put the robot at rest, standing, with its wheels on the ground at `xy`, leaning
        by `pitch` rad about the axle. Velocities and the wheel commands are zeroed."""
        self._enter(drop_contacts)
        client, body = self._client, self.body
        centre, orientation = legged_spawn_pose(
            pitch, yaw, xy, ground_height, self.model, self._com_forward
        )
        client.resetBasePositionAndOrientation(body, centre, orientation)
        client.resetBaseVelocity(body, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        for joint, angle in zip(self.leg_joints, self.model.standing, strict=True):
            client.resetJointState(body, joint, targetValue=angle, targetVelocity=0.0)
        for joint in self.wheel_joints:
            client.resetJointState(body, joint, targetValue=0.0, targetVelocity=0.0)
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
                tuple(joint[0] for joint in joints[:4]),
                tuple(joint[1] for joint in joints[:4]),
                (wheel_left, wheel_right),
                self.wheel_commands,
                math.atan2(-r20, r22),  # roll
                r01 * wx + r11 * wy + r21 * wz,  # roll rate
                position[2] - axle[2],
            )
        )


# -- the robot's face to its tasks ---------------------------------------------------


def _leg_fields(model: LeggedModel) -> tuple[ObservationField, ...]:
    angles = tuple(
        ObservationField(
            f"{leg.name}_angle",
            "rad",
            leg.lower,
            leg.upper,
            f"{leg.name.replace('_', ' ')} angle, 0 straight down, + forward",
        )
        for leg in model.legs
    )
    rates = tuple(
        ObservationField(
            f"{leg.name}_rate",
            "rad/s",
            -ENCODER_SPEED_RANGE,
            ENCODER_SPEED_RANGE,
            f"{leg.name.replace('_', ' ')} angular rate (encoder)",
        )
        for leg in model.legs
    )
    limit = model.wheel_speed_limit
    return (
        *angles,
        *rates,
        ObservationField("roll", "rad", -math.pi, math.pi, "torso lean towards its right side"),
        ObservationField(
            "roll_rate", "rad/s", -GYRO_RANGE, GYRO_RANGE, "gyro rate about the heading"
        ),
        ObservationField(
            "wheel_speed_difference",
            "rad/s",
            -2 * ENCODER_SPEED_RANGE,
            2 * ENCODER_SPEED_RANGE,
            "right wheel's speed minus the left's (encoders): + turns left",
        ),
        ObservationField(
            "wheel_command_difference",
            "rad/s",
            -2 * limit,
            2 * limit,
            "right wheel's command minus the left's",
        ),
    )


OBSERVATION_LAYOUT = shared_layout(LEGGED_MODEL.wheel_speed_limit, LEGGED_MODEL.top_speed) + (
    _leg_fields(LEGGED_MODEL)
)
_SIZE = len(OBSERVATION_LAYOUT)
_LOW = tuple(field.low for field in OBSERVATION_LAYOUT[5:])
_HIGH = tuple(field.high for field in OBSERVATION_LAYOUT[5:])

ACTION_LAYOUT = (
    *(f"{name}_target" for name in LEG_JOINT_NAMES),
    "left_wheel_change",
    "right_wheel_change",
)


def decode(action: Any, model: LeggedModel = LEGGED_MODEL) -> tuple[float, ...]:
    """The leg targets (rad) and wheel changes (rad/s) of an action of `Box(-1, 1, (6,))`.

    A leg value v aims the joint at centre + v * half range: -1 and 1 are the ends of the
    joint's range, and a value beyond them asks for a target outside it, which the body
    clips to the range. A wheel value is a change of that wheel's commanded speed of v
    rad/s and must lie in [-1, 1], as on the two-wheel bot. NaN, a wrong shape or a
    wheel value outside [-1, 1] raise a ValueError that says what was expected.
    """
    values = None
    if type(action) is np.ndarray and action.shape == (6,):
        values = action.tolist()
    else:
        try:
            array = np.asarray(action, dtype=np.float64)
            if array.shape == (6,):
                values = array.tolist()
        except (TypeError, ValueError):
            pass
    if values is not None and not any(v != v for v in values):
        left, right = values[4], values[5]
        if -1.0 <= left <= 1.0 and -1.0 <= right <= 1.0:
            legs = model.legs
            return (
                *(leg.centre + leg.half_range * v for leg, v in zip(legs, values[:4], strict=True)),
                left * MAX_WHEEL_SPEED_CHANGE,
                right * MAX_WHEEL_SPEED_CHANGE,
            )
    raise ValueError(
        f"wheel-legged action {action!r} is not in the action space: expected 6 finite "
        f"numbers {ACTION_LAYOUT}, the leg targets in [-1, 1] (the ends of each joint's "
        f"range; beyond them, clipped) and the wheel-speed changes in [-1, 1] (scaled to "
        f"at most {MAX_WHEEL_SPEED_CHANGE} rad/s)"
    )


def _clip(values, low, high):
    return [h if v > h else lo if v < lo else v for v, lo, h in zip(values, low, high, strict=True)]


class WheelLegged(Robot):
    """The wheel-legged balancer (`WheelLeggedBot`): continuous actions only."""

    name = "wheel-legged"
    summary = "a wheel-legged balancer: hip, knee and wheel per leg (1.2 kg)"
    urdf_path = URDF_PATH
    wheel_radius = LEGGED_MODEL.wheel_radius
    wheel_speed_limit = LEGGED_MODEL.wheel_speed_limit
    action_modes = ("continuous",)

    def body(self, client: BulletClient) -> WheelLeggedBot:
        return WheelLeggedBot(client)

    def action_space(self, action_mode: str) -> spaces.Space:
        self.check_action_mode(action_mode)
        return spaces.Box(-1.0, 1.0, shape=(len(ACTION_LAYOUT),), dtype=np.float32)

    def action_decoder(self, action_mode: str) -> Callable[[Any], tuple[float, ...]]:
        self.check_action_mode(action_mode)
        return decode

    def own_layout(self) -> tuple[ObservationField, ...]:
        return OBSERVATION_LAYOUT

    def observe(
        self,
        reading: tuple[float, float, float],
        command: float,
        target: float,
        state: LeggedState,
        scan: list[float] | None = None,
    ) -> np.ndarray:
        (speed_left, speed_right), (command_left, command_right) = (
            state.wheel_speeds,
            state.wheel_commands,
        )
        own = _clip(
            (
                *state.leg_angles,
                *state.leg_rates,
                state.roll,
                state.roll_rate,
                speed_right - speed_left,
                command_right - command_left,
            ),
            _LOW,
            _HIGH,
        )
        values = [*sensed(*reading), command, target, *own, *clipped_scan(scan or ())]
        return np.array(values, dtype=OBSERVATION_DTYPE)


WHEEL_LEGGED = WheelLegged()

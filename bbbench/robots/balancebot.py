"""The balancing bot: one body in a bullet world.

`BalanceBot` applies a wheel-speed command and reads the state with named
accessors; its tilt from vertical is what the task's rules judge a fall by
(`FALL_TILT`, `bbbench.tasks.reward.has_fallen`). It knows nothing of rewards,
observations or tasks.

Conventions (the robot's own frame):

- *forward* is the bot's +y axis; a positive wheel speed drives forward;
- *pitch* is the lean of the torso towards forward, relative to gravity, in the
  bot's sagittal plane (what an IMU's accelerometer measures): positive leans
  forward, 0 is upright, whatever the heading or the slope underfoot;
- *pitch rate* is the gyro reading about the axle (body -x), same sign as pitch;
- *wheel speed* is the mean speed of the two wheels relative to the torso
  (what the encoders measure), forward-positive;
- *forward velocity* is the true horizontal velocity of the axle's midpoint
  along the bot's heading, in m/s.
"""

from __future__ import annotations

import collections
import functools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import pybullet
from pybullet_utils.bullet_client import BulletClient

from bbbench.robots.body import Body, WheeledModel, rolling_radius, urdf_parts

URDF_PATH = Path(__file__).with_name("balancebot.urdf")

# Tilt from vertical (rad) past which the bot has fallen. Tilt is measured
# against gravity, so the test holds on slopes and bumps as on flat ground; a
# centre-of-mass height would not. Measured with the PD baseline at three gain
# settings: from rest, the wheels' torque limit brings the torso back from
# 0.9 rad but not from 1.0 rad. At 1 rad the first reward's upright term,
# 1 - |pitch|, also reaches 0.
FALL_TILT = 1.0


@dataclass(frozen=True)
class RobotModel(WheeledModel):
    """The robot's physical facts, read from its URDF (the one place they are written)."""

    urdf_path: Path
    wheel_joint_names: tuple[str, str]  # (left, right)
    wheel_radius: float  # m
    wheel_speed_limit: float  # rad/s, the motors' top speed
    motor_torque_limit: float  # N m per wheel, the velocity servo's effort limit
    axle_height: float  # m, axle above the link origin
    torso_com_height: float  # m, torso centre of mass above the link origin
    torso_top_height: float  # m, the top of the torso's box above the link origin

    @property
    def com_above_axle(self) -> float:
        """Height of the torso's centre of mass above the axle, m."""
        return self.torso_com_height - self.axle_height

    @property
    def top_above_com(self) -> float:
        """m: the top of the torso above its centre of mass (where a beam is hinged)."""
        return self.torso_top_height - self.torso_com_height


def read_model(urdf_path: Path = URDF_PATH) -> RobotModel:
    """Parse the facts `BalanceBot` needs out of the URDF."""
    joints, links = urdf_parts(urdf_path)
    left, right = joints["left_wheel_joint"], joints["right_wheel_joint"]
    limit = left.find("limit")
    torso = links[left.find("parent").get("link")]
    return RobotModel(
        urdf_path=urdf_path,
        wheel_joint_names=(left.get("name"), right.get("name")),
        wheel_radius=rolling_radius(links, left),
        wheel_speed_limit=float(limit.get("velocity")),
        motor_torque_limit=float(limit.get("effort")),
        axle_height=float(left.find("origin").get("xyz").split()[2]),
        torso_com_height=float(torso.find("inertial/origin").get("xyz").split()[2]),
        torso_top_height=float(torso.find("collision/origin").get("xyz").split()[2])
        + float(torso.find("collision/geometry/box").get("size").split()[2]) / 2,
    )


MODEL = read_model()


class BotState(NamedTuple):
    """One reading of the bot. Angles in rad, rates in rad/s, velocities in m/s."""

    # The torso's centre of mass as built (unmoved by `set_com_offset`), world frame (m)
    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]  # torso quaternion (x, y, z, w)
    pitch: float
    pitch_rate: float
    tilt: float  # angle between the torso's axis and vertical, >= 0
    wheel_speed: float
    forward_velocity: float
    velocity: tuple[float, float]  # the axle's horizontal velocity, world frame (m/s)
    heading: tuple[float, float]  # the bot's forward direction, horizontal unit vector
    axle: tuple[float, float, float]  # the axle's midpoint, world frame (m)


def tilt_from_quaternion(orientation: tuple[float, float, float, float]) -> float:
    """Angle (rad) between the torso's axis and vertical: acos of the body z axis's height."""
    qx, qy, _, _ = orientation
    return math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * (qx * qx + qy * qy))))


def spawn_pose(
    pitch: float,
    yaw: float = 0.0,
    xy: tuple[float, float] = (0.0, 0.0),
    ground_height: float = 0.0,
    model: RobotModel = MODEL,
    com_forward: float = 0.0,
) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
    """Torso centre of mass and orientation with the wheels on the ground at `xy`, leaning
    by `pitch` rad about the axle: the base pose pybullet's reset takes. `com_forward`
    (m): the centre of mass is that far ahead of the axle along the torso's y axis."""
    orientation = pybullet.getQuaternionFromEuler((-pitch, 0.0, yaw))
    axle = (xy[0], xy[1], ground_height + model.wheel_radius)
    matrix = pybullet.getMatrixFromQuaternion(orientation)
    up = matrix[2::3]  # body z axis in world
    com = tuple(a + model.com_above_axle * u for a, u in zip(axle, up, strict=True))
    if com_forward:
        forward = matrix[1::3]  # body y axis in world
        com = tuple(c + com_forward * f for c, f in zip(com, forward, strict=True))
    return com, orientation


# namedtuple's generated __new__ is a Python call; tuple.__new__ skips it on the hot path.
_new_state = functools.partial(tuple.__new__, BotState)


class BalanceBot(Body):
    """One balancing bot in a bullet world.

    Args:
        client: the world's bullet client (one per environment).
        model: physical facts of the robot; the default is read from `balancebot.urdf`.

    The body is loaded with `URDF_USE_INERTIA_FROM_FILE` so pybullet uses the
    file's inertias, and the wheel servos use the file's finite torque limit.
    """

    def __init__(self, client: BulletClient, model: RobotModel = MODEL) -> None:
        self.model = model
        super().__init__(client, model.urdf_path, model.wheel_joint_names)
        self._com_above_axle = model.com_above_axle
        self._motor_forces = (model.motor_torque_limit, model.motor_torque_limit)
        self._delayed: collections.deque[float] | None = None  # servo targets not yet sent
        self.wheel_command = 0.0  # rad/s the servos are asked for; set by command_wheel_speed
        self.command_wheel_speed(0.0)

    def _actuate(self) -> None:
        self.command_wheel_speed(self.wheel_command)

    def _stop(self) -> None:
        self.command_wheel_speed(0.0)

    # -- acting ---------------------------------------------------------------

    def set_motor_strength(self, factor: float) -> None:
        """Servos `factor` times as strong as the URDF's torque limit (1: as built)."""
        limit = self.model.motor_torque_limit * factor
        self._motor_forces = (limit, limit)

    @property
    def motor_forces(self) -> tuple[float, float]:
        """The wheel servos' torque limits now (N m): the URDF's, times the motor strength."""
        return self._motor_forces

    def set_action_delay(self, steps: int) -> None:
        """Send each wheel-speed command to the servos `steps` commands later (0: at
        once). `wheel_command` stays the command asked for; the servos hold the one
        asked for `steps` commands before it (0 rad/s for the first `steps` after a reset).
        """
        self._delayed = collections.deque([0.0] * steps) if steps else None

    def act(self, change: float) -> float:
        """Change the commanded wheel speed by `change` rad/s (an action of the table in
        `bbbench.robots.twowheel`); return the command now held (`command_wheel_speed`)."""
        return self.command_wheel_speed(self.wheel_command + change)

    def command_wheel_speed(self, speed: float) -> float:
        """Drive both wheels' velocity servos at `speed` rad/s (forward-positive).

        The command is clamped to the wheel-speed limit; the applied value is
        returned and kept in `wheel_command`. NaN raises ValueError.
        """
        limit = self.model.wheel_speed_limit
        if speed > limit:
            speed = limit
        elif speed < -limit:
            speed = -limit
        elif speed != speed:
            raise ValueError("wheel speed command is NaN; expected a number of rad/s")
        held = speed
        if self._delayed is not None:  # `set_action_delay`: the servos get an older one
            self._delayed.append(speed)
            held = self._delayed.popleft()
        pybullet.setJointMotorControlArray(
            self.body,
            self.wheel_joints,
            pybullet.VELOCITY_CONTROL,
            targetVelocities=(held, -held),
            forces=self._motor_forces,
            physicsClientId=self._client_id,
        )
        self.wheel_command = speed
        return speed

    # `reset` (Body's): the torso tilted about the axle, so the wheels touch the ground
    # whatever the lean.
    def _spawn_pose(self, pitch, yaw, xy, ground_height):
        return spawn_pose(pitch, yaw, xy, ground_height, self.model, self._com_forward)

    def _hold_still(self) -> None:
        if self._delayed is not None:
            self._delayed = collections.deque([0.0] * len(self._delayed))
        self.command_wheel_speed(0.0)

    # -- sensing --------------------------------------------------------------

    def read(self) -> BotState:
        """Query the world once and return the bot's state in its own frame.

        Plain float arithmetic: this runs every step, where numpy's per-call
        cost on 3-vectors would dominate. Positional client ids: pybullet
        parses them faster than keywords.
        """
        body, client_id = self.body, self._client_id
        position, orientation = pybullet.getBasePositionAndOrientation(body, client_id)
        (vx, vy, _), (wx, wy, wz) = pybullet.getBaseVelocity(body, client_id)
        left, right = pybullet.getJointStates(body, self.wheel_joints, client_id)
        # The torso's rotation matrix, row-major. Its columns are the body's x (axle),
        # y (forward) and z (up) axes in the world; its last row is world "up" seen
        # from the body, which gives pitch and tilt against gravity.
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = pybullet.getMatrixFromQuaternion(orientation)
        # Velocity of the axle's midpoint: v_com + w x (-d * body_z).
        d = self._com_above_axle
        vx -= d * (wy * r22 - wz * r12)
        vy -= d * (wz * r02 - wx * r22)
        e = self._com_forward
        if e:  # `set_com_offset`: the axle is also e behind the centre of mass, along y
            vx -= e * (wy * r21 - wz * r11)
            vy -= e * (wz * r01 - wx * r21)
            px, py, pz = position
            position = (px - e * r01, py - e * r11, pz - e * r21)  # as if unshifted
        length = math.hypot(r01, r11)  # horizontal length of the forward axis
        # Pointing straight up or down there is no heading: say +y.
        heading = (r01 / length, r11 / length) if length > 1e-9 else (0.0, 1.0)
        px, py, pz = position
        # `tilt_from_quaternion`, inline (this runs every step): the same operations, and
        # the same clamping as its max(-1, min(1, .)), NaN included.
        qx, qy = orientation[0], orientation[1]
        up = 1.0 - 2.0 * (qx * qx + qy * qy)
        up = up if up < 1.0 else 1.0
        return self._reading(
            (
                position,
                orientation,
                math.atan2(-r21, r22),  # pitch
                0.0 - (r00 * wx + r10 * wy + r20 * wz),  # pitch rate; "0.0 -": no -0.0 at rest
                math.acos(up if up > -1.0 else -1.0),  # tilt
                # The right wheel's axis is reversed: its forward speed is minus its joint's.
                0.5 * (left[1] - right[1]),  # wheel speed
                vx * heading[0] + vy * heading[1],  # forward velocity
                (vx, vy),
                heading,
                (px - d * r02, py - d * r12, pz - d * r22),  # axle
            ),
            (wx, wy, wz),
            (r02, r12, r22),
            left[1],
            right[1],
        )

    def _reading(
        self,
        shared: tuple,
        rates: tuple[float, float, float],
        up: tuple[float, float, float],
        left: float,
        right: float,
    ) -> BotState:
        """The state `read` returns, from `BotState`'s values and what it read of the
        world: the torso's angular velocity (world frame), its up axis and each wheel
        joint's speed. A body that senses more from the same query (the steering bot's
        gyro about the up axis, its encoders apart) extends the state here."""
        return _new_state(shared)

    # Named readings for interactive use; each queries the world. In a loop, call
    # `read()` once and use its fields.
    @property
    def pitch(self) -> float:
        return self.read().pitch

    @property
    def pitch_rate(self) -> float:
        return self.read().pitch_rate

    @property
    def wheel_speed(self) -> float:
        return self.read().wheel_speed

    @property
    def forward_velocity(self) -> float:
        return self.read().forward_velocity

    @property
    def wheel_speeds(self) -> tuple[float, float]:
        """(left, right) wheel speeds relative to the torso, rad/s, forward-positive."""
        left, right = self._client.getJointStates(self.body, self.wheel_joints)
        return left[1], -right[1]

    @property
    def pose(self) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
        """(centre-of-mass position in m, orientation quaternion (x, y, z, w))."""
        state = self.read()
        return state.position, state.orientation

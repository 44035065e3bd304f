"""The steering robot's body: `SteeringBot`, the two-wheel bot's body and motors with its
wheels commanded apart, and its state (`SteerState`). `bbbench.robots.steering` is its face
to its tasks (actions and observation layout) and documents the robot."""

from __future__ import annotations

import collections
import functools
from typing import NamedTuple

import pybullet
from pybullet_utils.bullet_client import BulletClient

from bbbench.robots.balancebot import MODEL, BalanceBot, RobotModel

# The largest turning command (rad/s): about 5 rad/s of yaw rate; each wheel's speed is
# still clamped to the wheels' limit.
TURN_LIMIT = 6.0


class SteerState(NamedTuple):
    """One reading of the steering bot: `BotState`'s fields, then its own. Angles in rad,
    rates in rad/s, velocities in m/s."""

    position: tuple[float, float, float]  # the torso's centre of mass as built, world frame
    orientation: tuple[float, float, float, float]  # torso quaternion (x, y, z, w)
    pitch: float
    pitch_rate: float
    tilt: float
    wheel_speed: float  # the mean of the two wheels, relative to the torso
    forward_velocity: float
    velocity: tuple[float, float]  # the axle's horizontal velocity, world frame
    heading: tuple[float, float]  # the bot's forward direction, horizontal unit vector
    axle: tuple[float, float, float]  # the axle's midpoint, world frame (m)
    yaw_rate: float  # the gyro about the torso's up axis, + turning left
    wheel_speed_difference: float  # right - left, relative to the torso (encoders)
    turn_command: float  # rad/s: the right wheel's command above the forward one


_new_state = functools.partial(tuple.__new__, SteerState)


class SteeringBot(BalanceBot):
    """The balancing bot with its wheels commanded apart (`command_wheels`).

    `wheel_command` is the forward command u and `turn_command` the turning command d
    (rad/s); the servos hold u - d on the left wheel and u + d on the right, each clamped
    to the wheel-speed limit. `read` returns a `SteerState`.
    """

    def __init__(self, client: BulletClient, model: RobotModel = MODEL) -> None:
        self.turn_command = 0.0
        super().__init__(client, model)

    def act(self, change: tuple[float, float]) -> float:
        """Change the forward and turning commands by `change` (rad/s each); return the
        forward command now held."""
        forward, turn = change
        return self.command_wheels(self.wheel_command + forward, self.turn_command + turn)

    def command_wheel_speed(self, speed: float) -> float:
        """Both wheels at `speed` rad/s apart from the turning command held."""
        return self.command_wheels(speed, self.turn_command)

    def command_wheels(self, forward: float, turn: float) -> float:
        """Drive the wheels at `forward` - `turn` (left) and `forward` + `turn` (right)
        rad/s. `forward` is clamped to the wheel-speed limit and `turn` to `TURN_LIMIT`;
        each wheel's speed to the limit. Returns the forward command, kept in
        `wheel_command` (and the turning one in `turn_command`). NaN raises ValueError."""
        if forward != forward or turn != turn:
            raise ValueError("wheel speed command is NaN; expected numbers of rad/s")
        limit = self.model.wheel_speed_limit
        # Clamps as conditionals, not min(max()): this runs every step (the same values).
        forward = limit if forward > limit else -limit if forward < -limit else forward
        turn = TURN_LIMIT if turn > TURN_LIMIT else -TURN_LIMIT if turn < -TURN_LIMIT else turn
        held_forward, held_turn = forward, turn
        if self._delayed is not None:  # `set_action_delay`: the servos get an older pair
            self._delayed.append((forward, turn))
            held_forward, held_turn = self._delayed.popleft()
        left, right = held_forward - held_turn, held_forward + held_turn
        left = limit if left > limit else -limit if left < -limit else left
        right = limit if right > limit else -limit if right < -limit else right
        pybullet.setJointMotorControlArray(
            self.body,
            self.wheel_joints,
            pybullet.VELOCITY_CONTROL,
            targetVelocities=(left, -right),  # the right wheel's axis is reversed
            forces=self._motor_forces,
            physicsClientId=self._client_id,
        )
        self.wheel_command, self.turn_command = forward, turn
        return forward

    def set_action_delay(self, steps: int) -> None:
        """As the two-wheel bot's: the servos hold the pair of commands asked `steps`
        commands before (both 0 for the first `steps` after a reset)."""
        self._delayed = collections.deque([(0.0, 0.0)] * steps) if steps else None

    def _hold_still(self) -> None:
        if self._delayed is not None:
            self._delayed = collections.deque([(0.0, 0.0)] * len(self._delayed))
        self.command_wheels(0.0, 0.0)

    def _stop(self) -> None:
        self.command_wheels(0.0, 0.0)

    def _reading(
        self,
        shared: tuple,
        rates: tuple[float, float, float],
        up: tuple[float, float, float],
        left: float,
        right: float,
    ) -> SteerState:
        """`BalanceBot.read`'s reading (the world queried once), then the yaw rate, the
        wheels' speed difference and the turning command."""
        wx, wy, wz = rates
        r02, r12, r22 = up
        return _new_state(
            (
                *shared,
                r02 * wx + r12 * wy + r22 * wz,  # yaw rate: about the torso's up axis
                0.0 - right - left,  # right - left, forward-positive each
                self.turn_command,
            )
        )

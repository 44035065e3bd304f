"""Robot models: each robot's URDF, the class that owns one body in a world, and its
`Robot` (actions and observation layout), found by the name a task spec gives."""

from bbbench.robots.balancebot import (
    FALL_TILT,
    MODEL,
    URDF_PATH,
    BalanceBot,
    BotState,
    RobotModel,
    read_model,
)
from bbbench.robots.body import Body
from bbbench.robots.robot import Robot, registered
from bbbench.robots.steering import TWO_WHEEL_STEER
from bbbench.robots.steering_body import SteeringBot, SteerState
from bbbench.robots.twowheel import TWO_WHEEL
from bbbench.robots.wheel_legged import WHEEL_LEGGED

ROBOTS: dict[str, Robot] = registered((TWO_WHEEL, WHEEL_LEGGED, TWO_WHEEL_STEER))


def robot(name: str) -> Robot:
    """The robot called `name` (`TaskSpec.robot`), or a KeyError that lists them."""
    try:
        return ROBOTS[name]
    except KeyError:
        raise KeyError(f"no robot {name!r}: the robots are {', '.join(ROBOTS)}") from None


__all__ = [
    "FALL_TILT",
    "MODEL",
    "ROBOTS",
    "TWO_WHEEL",
    "TWO_WHEEL_STEER",
    "URDF_PATH",
    "WHEEL_LEGGED",
    "BalanceBot",
    "Body",
    "BotState",
    "Robot",
    "RobotModel",
    "SteerState",
    "SteeringBot",
    "read_model",
    "robot",
]

"""Robot models: the URDF and the class that owns one body in a world."""

from bbbench.robots.balancebot import (
    FALL_TILT,
    MODEL,
    URDF_PATH,
    BalanceBot,
    BotState,
    RobotModel,
    read_model,
)

__all__ = [
    "FALL_TILT",
    "MODEL",
    "URDF_PATH",
    "BalanceBot",
    "BotState",
    "RobotModel",
    "read_model",
]

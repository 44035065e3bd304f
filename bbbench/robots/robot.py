"""`Robot`: what a task needs to know of the robot it plays, one object per robot.

A task spec names its robot (`TaskSpec.robot`); everything that depends on the
robot's body asks that object: the body the scene builds in a world, the action
spaces and how an action becomes a command, and the observation layout. Nothing
else in bbbench assumes two wheels or two legs.

Every robot's observation begins with the five shared values
(`bbbench.robots.layout.shared_layout`), so a controller of those values reads any
robot's observation; its own fields follow them, then the optional height scan.
"""

from __future__ import annotations

import copy
import functools
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from pybullet_utils.bullet_client import BulletClient

from bbbench.robots.body import Body, WheeledModel
from bbbench.robots.layout import HEIGHT_SCAN_LAYOUT, SHARED_FIELDS, ObservationField, box


class Robot:
    """A robot of the suite: its name, facts, body, actions and observation layout.

    Subclasses set the class attributes and write `body`, `action_space`,
    `action_decoder`, `own_layout` and `observe`; one instance per robot lives in
    `bbbench.robots.ROBOTS`, under its `name`. Its physical facts are its `model`'s,
    read from its URDF.
    """

    name: ClassVar[str]  # what `TaskSpec.robot` holds
    summary: ClassVar[str]  # one line, for `bbbench list` and error messages
    model: ClassVar[WheeledModel]  # the facts read from its URDF
    action_modes: ClassVar[tuple[str, ...]]  # the first is the default
    # The built-in policy that is its tasks' classical controller, where the task's
    # scenario names none (`Scenario.controller`).
    controller: ClassVar[str]

    @property
    def urdf_path(self) -> Path:
        """The robot's URDF: hashed into every fingerprint of its tasks."""
        return self.model.urdf_path

    @property
    def wheel_radius(self) -> float:
        """m"""
        return self.model.wheel_radius

    @property
    def top_speed(self) -> float:
        """Forward speed at the wheel-speed limit, m/s: no target may ask for more."""
        return self.model.top_speed

    @property
    def observes_shared_only(self) -> bool:
        """Whether the robot's observation is the shared five values and nothing more,
        so that the env may build it with `bbbench.robots.layout.observe` directly."""
        return len(self.own_layout()) == len(SHARED_FIELDS)

    @property
    def default_action_mode(self) -> str:
        return self.action_modes[0]

    def check_action_mode(self, action_mode: str) -> None:
        """A clear ValueError for an action mode the robot does not take."""
        if action_mode not in self.action_modes:
            raise ValueError(
                f"action_mode must be one of {self.action_modes} for the {self.name} robot, "
                f"got {action_mode!r}"
            )

    def body(self, client: BulletClient) -> Body:
        """A new body of the robot in `client`'s world."""
        raise NotImplementedError

    def action_space(self, action_mode: str) -> spaces.Space:
        raise NotImplementedError

    def action_decoder(self, action_mode: str) -> Callable[[Any], Any]:
        """The function from an action of `action_space(action_mode)` to what the body's
        `act` takes; it raises a ValueError that says what was expected for an action
        outside the space."""
        raise NotImplementedError

    def own_layout(self) -> tuple[ObservationField, ...]:
        """The robot's fields: the shared five, then what the robot adds."""
        raise NotImplementedError

    def layout(self, height_scan: bool = False) -> tuple[ObservationField, ...]:
        """The fields of the observation, in order: the robot's, then the scan if asked."""
        fields = self.own_layout()
        return fields + HEIGHT_SCAN_LAYOUT if height_scan else fields

    def observation_space(self, height_scan: bool = False) -> spaces.Box:
        """The Box every single-bot task of the robot observes in: a copy of one built
        once, a new object each call. A space carries its own random generator, and a
        policy zip pickles it: an env sharing it with every other env of the process
        wrote zips whose bytes depended on what the process had sampled before."""
        return copy.deepcopy(_space(self, height_scan))

    def observe(
        self,
        reading: tuple[float, float, float],
        command: float,
        target: float,
        state: Any,
        scan: list[float] | None = None,
    ) -> np.ndarray:
        """The observation: `reading` (pitch, pitch rate and wheel speed as sensed), the
        wheel command, the target velocity, what the robot adds from `state`, then the
        height `scan` if given."""
        raise NotImplementedError

    def values(
        self, reading: tuple[float, float, float], command: float, target: float, state: Any
    ) -> tuple[float, ...]:
        """`observe`'s values without the scan, as Python floats: the robot's own layout, the
        shared five first. For callers that build many observations at once (a multi-bot
        scenario appends its own terms to them)."""
        raise NotImplementedError

    def interface_markdown(self) -> str:
        """The action and observation spaces as Markdown tables, for its tasks' docstrings."""
        raise NotImplementedError

    def task_interface(self) -> str:
        """What its task classes' docstrings say of its spaces (`bbbench.envs.task_envs`)."""
        return (
            f"{self.interface_markdown()}\n\nThe reward, starting state, episode end and "
            "keywords are on the task's page (docs/environments/); `BalanceEnv` documents "
            f"the API, which the {self.name} robot plays as the two-wheel bot does."
        )

    def actions_markdown(self) -> str:
        """The action spaces (every mode) in Markdown, for the site's task pages."""
        raise NotImplementedError

    def describe_layout(self, height_scan: bool = False) -> str:
        """'Box(5,) (two-wheel: pitch, ..., target_velocity)': for error messages."""
        fields = self.layout(height_scan)
        names = [field.name for field in fields]
        if height_scan:
            names = [*names[: -len(HEIGHT_SCAN_LAYOUT)], f"{len(HEIGHT_SCAN_LAYOUT)} heights"]
        return f"Box({len(fields)},) ({self.name}: {', '.join(names)})"

    def __repr__(self) -> str:
        return f"<robot {self.name}>"


@functools.cache
def _space(robot: Robot, height_scan: bool) -> spaces.Box:
    return box(robot.layout(height_scan))


# What a robot declares (class attributes) and writes (methods): `registered` refuses a
# robot without one, when the robot is registered rather than when a task plays it.
DECLARED = ("name", "summary", "model", "action_modes", "controller")
WRITTEN = ("body", "action_space", "action_decoder", "own_layout", "observe")


def registered(robots: Iterable[Robot]) -> dict[str, Robot]:
    """`robots` by name (`bbbench.robots.ROBOTS`): a TypeError that names what a robot
    lacks of `DECLARED` and `WRITTEN`, a ValueError for a name given twice."""
    table: dict[str, Robot] = {}
    for robot in robots:
        kind = type(robot)
        lacks = [name for name in DECLARED if not hasattr(kind, name)]
        lacks += [f"{name}()" for name in WRITTEN if getattr(kind, name) is getattr(Robot, name)]
        if lacks:
            raise TypeError(
                f"robot {kind.__name__} lacks {', '.join(lacks)}: a robot declares "
                f"{', '.join(DECLARED)} and writes {', '.join(WRITTEN)} (bbbench/robots/robot.py)"
            )
        if robot.name in table:
            raise ValueError(f"two robots are called {robot.name!r}")
        table[robot.name] = robot
    return table

"""`Solo`: one bot alone in its world, every single-bot task's scenario."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from bbbench.robots.layout import SCAN_OFFSETS, observe
from bbbench.tasks.reward import step_outcome
from bbbench.tasks.scenarios.base import Pose, Scenario


class Solo(Scenario):
    """One bot at the origin heading along +y, leaning U(-initial_pitch, initial_pitch);
    it observes its robot's layout through the task's sensors (then, with the height scan,
    the ground ahead), earns the shared reward for its own target, and a fall ends it."""

    name = "solo"
    summary = "one bot alone, at the origin heading along +y"

    def __init__(self, task) -> None:
        super().__init__(task)
        self._space = self.robot.observation_space(task.height_scan)
        self._reward_of = step_outcome

    def starts(self, rng: np.random.Generator) -> tuple[list[Pose], list[float]]:
        pitch = self.task.initial_pitch
        return [((0.0, 0.0), 0.0)], [rng.uniform(-pitch, pitch)]

    def observation_space(self) -> spaces.Box:
        return self._space

    def observe_one(
        self, scene: Any, state: Any, command: float, target: float, step: int
    ) -> np.ndarray:
        """The bot's observation: its reading through the task's sensors, then what its
        robot adds; with the height scan, then the ground heights ahead of the axle."""
        if scene.plain:  # perfect sensors, the shared five alone: the hot path
            return observe(state.pitch, state.pitch_rate, state.wheel_speed, command, target)
        reading = scene.reading(state, step)
        scan = None
        if self.task.height_scan:
            x, y, axle_height = state.axle
            scan = scene.ground.heights_along(x, y, state.heading, SCAN_OFFSETS, axle_height)
        return self.robot.observe(reading, command, target, state, scan)

    def outcome_one(self, state: Any, target: float) -> tuple[float, bool, dict[str, Any]]:
        """The step's reward, whether the bot fell, and its info (`step_outcome`)."""
        return self._reward_of(state, target, self.reward)

"""`Solo`: one bot alone in its world, every single-bot task's scenario."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from bbbench.robots.layout import SCAN_OFFSETS, observe
from bbbench.tasks.reward import step_outcome
from bbbench.tasks.scenarios.base import Outcome, Pose, Scenario


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

    def observe(
        self, scene: Any, states: list[Any], commands: list[float], targets: list[float], step: int
    ) -> list[np.ndarray]:
        """The bot's observation, as the one row of a list: its reading through the
        task's sensors, then what its robot adds; with the height scan, then the ground
        heights ahead of the axle."""
        state, command, target = states[0], commands[0], targets[0]
        if scene.true_five_only:  # perfect sensors, the shared five alone: the hot path
            return [observe(state.pitch, state.pitch_rate, state.wheel_speed, command, target)]
        reading = scene.reading(state, step)
        scan = None
        if self.task.height_scan:
            x, y, axle_height = state.axle
            scan = scene.ground.heights_along(x, y, state.heading, SCAN_OFFSETS, axle_height)
        return [self.robot.observe(reading, command, target, state, scan)]

    def outcome(
        self, agents: list[str], states: list[Any], targets: list[float], seed: int
    ) -> Outcome:
        """The step's reward, whether the bot fell (which ends its episode), and its
        info (`step_outcome`)."""
        reward, fell, info = self._reward_of(states[0], targets[0], self.reward)
        return Outcome((reward,), (fell,), fell, f"{agents[0]} fell" if fell else "", (info,))

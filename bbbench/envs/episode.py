"""`EpisodeDraw`: what an episode's seed drew (`Scene.episode`), read-only."""

from __future__ import annotations

import functools

import numpy as np

from bbbench.terrain import Heightmap


def _read_only(array: np.ndarray) -> np.ndarray:
    array.flags.writeable = False
    return array


class EpisodeDraw:
    """What an episode's seed drew, read-only (`scene.episode`).

    The arrays are built on first use: a reset on the hot path of training pays for the
    values it draws, not for their copies.
    """

    def __init__(
        self,
        seed: int,
        targets: list[list[float]],
        sensor_errors: list | None,  # per step (one bot), or per bot and step
        heightmap: Heightmap | None,
        poses: list[tuple[tuple[float, float], float]],
        pitches,
        pushes: tuple[tuple[int, int, float], ...] = (),
    ) -> None:
        self.seed = seed
        self.heightmap = heightmap  # the terrain; None for flat ground
        self.poses = tuple(poses)  # per bot: (x, y) m, yaw rad
        self.pitches = tuple(float(p) for p in pitches)  # per bot: the initial lean, rad
        self.pushes = pushes  # (step, bot, N s along its heading), in order: `push`'s shoves
        self._rows, self._errors = targets, sensor_errors

    @functools.cached_property
    def targets(self) -> np.ndarray:
        """(bots, max_episode_steps + 1): bot i's target forward velocity (m/s) after reset
        (column 0) and after each step."""
        return _read_only(np.array(self._rows, dtype=np.float64))

    @functools.cached_property
    def sensor_errors(self) -> np.ndarray | None:
        """(max_episode_steps + 1, 3): the error added to (pitch, pitch rate, wheel speed)
        at each step, bias included; (bots, max_episode_steps + 1, 3) for several bots;
        None for perfect sensors."""
        return None if self._errors is None else _read_only(np.array(self._errors))

"""Flat ground."""

from __future__ import annotations

from dataclasses import dataclass

from pybullet_utils.bullet_client import BulletClient

from bbbench.terrain.bullet import GROUND_FRICTION, add_ground_plane


@dataclass(frozen=True)
class FlatGround:
    """An infinite plane at z = 0."""

    friction: float = GROUND_FRICTION

    def load(self, client: BulletClient) -> int:
        """Add the ground to a world; return its body id."""
        return add_ground_plane(client, self.friction)

    def height_at(self, x: float, y: float) -> float:
        """Ground height (m) at a point: where to put the wheels."""
        return 0.0

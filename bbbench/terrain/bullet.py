"""Loading ground into a bullet world."""

from __future__ import annotations

import os

import pybullet
import pybullet_data
from pybullet_utils.bullet_client import BulletClient

from bbbench.terrain.heightmap import Heightmap

# Bullet multiplies the friction of the two bodies in contact: a ground of 1.0
# leaves each body's own friction (the bot's wheels: 0.8) as the contact's.
GROUND_FRICTION = 1.0

# A checkered, tiled plane: motion is visible in rendered frames.
_PLANE_MESH = os.path.join(pybullet_data.getDataPath(), "plane100.obj")


def add_ground_plane(
    client: BulletClient, friction: float = GROUND_FRICTION, height: float = 0.0
) -> int:
    """Add an infinite flat ground at z = `height` and return its body id."""
    collision = client.createCollisionShape(pybullet.GEOM_PLANE)
    visual = client.createVisualShape(pybullet.GEOM_MESH, fileName=_PLANE_MESH)
    ground = client.createMultiBody(
        baseMass=0.0,
        baseCollisionShapeIndex=collision,
        baseVisualShapeIndex=visual,
        basePosition=(0.0, 0.0, height),
    )
    client.changeDynamics(ground, -1, lateralFriction=friction)
    return ground


class HeightfieldBody:
    """A bullet heightfield whose heights are replaced in place, one terrain per episode.

    Bullet centres a heightfield on its bounding box and keeps the box of the
    heights it was created with, even when they are replaced. So the shape is
    created once spanning `height_bounds` (the generator's stated bounds) and
    placed accordingly; every later terrain of the same grid fits inside it.
    """

    def __init__(
        self,
        client: BulletClient,
        grid_shape: tuple[int, int],
        cell_size: float,
        height_bounds: tuple[float, float],
        friction: float = GROUND_FRICTION,
    ) -> None:
        self._client = client
        self.grid_shape = grid_shape
        self.cell_size = cell_size
        self.height_bounds = height_bounds
        low, high = height_bounds
        spanning = [low] * (grid_shape[0] * grid_shape[1])
        spanning[-1] = high
        self.shape = self._heightfield(spanning)
        self.body = client.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=self.shape)
        client.changeDynamics(self.body, -1, lateralFriction=friction)
        client.changeVisualShape(self.body, -1, rgbaColor=(0.55, 0.62, 0.5, 1.0))

    def _heightfield(self, data: list[float], replace: int | None = None) -> int:
        extra = {} if replace is None else {"replaceHeightfieldIndex": replace}
        return self._client.createCollisionShape(
            pybullet.GEOM_HEIGHTFIELD,
            meshScale=(self.cell_size, self.cell_size, 1.0),
            heightfieldData=data,
            numHeightfieldRows=self.grid_shape[0],
            numHeightfieldColumns=self.grid_shape[1],
            **extra,
        )

    def show(self, heightmap: Heightmap) -> None:
        """Replace the heights with `heightmap`'s and move the field to its place."""
        if heightmap.shape != self.grid_shape:
            raise ValueError(f"heightmap of shape {heightmap.shape}, expected {self.grid_shape}")
        low, high = self.height_bounds
        if heightmap.heights.min() < low - 1e-9 or heightmap.heights.max() > high + 1e-9:
            raise ValueError(f"heights outside the field's bounds {self.height_bounds}")
        # Bullet reads element i + j * rows as (x-index i, y-index j): column-major.
        self._heightfield(heightmap.heights.ravel(order="F").tolist(), replace=self.shape)
        center_x, center_y = heightmap.center
        self._client.resetBasePositionAndOrientation(
            self.body, (center_x, center_y, (low + high) / 2.0), (0.0, 0.0, 0.0, 1.0)
        )

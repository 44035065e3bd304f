"""Loading ground into a bullet world."""

from __future__ import annotations

import os

import pybullet
import pybullet_data
from pybullet_utils.bullet_client import BulletClient

from bbbench.terrain.flat import GROUND_FRICTION, FlatGround
from bbbench.terrain.heightmap import HeightfieldTerrain, Heightmap

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


# The bot's wheels span 0.12 m either side of its centre: spawn above the highest node there.
_SPAWN_RADIUS = 0.15  # m


class PlaneGround:
    """Flat ground in a world; the same every episode."""

    def __init__(self, client: BulletClient, terrain: FlatGround) -> None:
        self.body = add_ground_plane(client, terrain.friction)

    def reset(self, rng) -> float:
        """Nothing to draw: the spawn height is 0."""
        return 0.0

    def spawn_height(self, x: float, y: float) -> float:
        """Height (m) to set a bot's wheels at to stand at (x, y): 0."""
        return 0.0


# m: how far the flat ground around a terrain strip reaches; more than a bot can
# drive in an episode (15 s at the motors' 2.46 m/s top speed).
_SURROUND = 50.0
_SURROUND_DEPTH = 1.0  # m: the thickness of its boxes


def add_flat_surround(
    client: BulletClient,
    bounds: tuple[float, float, float, float],
    friction: float = GROUND_FRICTION,
) -> list[int]:
    """Flat ground at z = 0 around the rectangle `bounds`, as four static boxes.

    Boxes, not a plane under everything: a plane's pair with each wheel is
    checked every step (measured: 3-5% of a terrain step), a box's only when
    the bot is near it.
    """
    x_min, x_max, y_min, y_max = bounds
    far = _SURROUND
    pieces = [  # (x from, x to, y from, y to): left and right full length, then the ends
        (-far, x_min, -far, far),
        (x_max, far, -far, far),
        (x_min, x_max, -far, y_min),
        (x_min, x_max, y_max, far),
    ]
    bodies = []
    for x0, x1, y0, y1 in pieces:
        half = ((x1 - x0) / 2.0, (y1 - y0) / 2.0, _SURROUND_DEPTH / 2.0)
        body = client.createMultiBody(
            baseMass=0.0,
            baseCollisionShapeIndex=client.createCollisionShape(
                pybullet.GEOM_BOX, halfExtents=half
            ),
            baseVisualShapeIndex=client.createVisualShape(
                pybullet.GEOM_BOX, halfExtents=half, rgbaColor=(0.5, 0.5, 0.5, 1.0)
            ),
            basePosition=((x0 + x1) / 2.0, (y0 + y1) / 2.0, -_SURROUND_DEPTH / 2.0),
        )
        client.changeDynamics(body, -1, lateralFriction=friction)
        bodies.append(body)
    return bodies


class HeightfieldGround:
    """Procedural ground in a world: a new heightmap each episode, flat ground around it."""

    def __init__(self, client: BulletClient, terrain: HeightfieldTerrain) -> None:
        self.terrain = terrain
        self.field = HeightfieldBody(
            client, terrain.grid_shape, terrain.cell_size, terrain.height_bounds
        )
        self.body = self.field.body
        self.surround = add_flat_surround(client, terrain.bounds)
        self.heightmap: Heightmap | None = None

    def reset(self, rng) -> float:
        """Draw this episode's terrain from `rng`, show it, and return the spawn height (m)."""
        self.heightmap = self.terrain.generate(rng)
        self.field.show(self.heightmap)
        return self.spawn_height(0.0, 0.0)

    def spawn_height(self, x: float, y: float) -> float:
        """Height (m) to set a bot's wheels at to stand at (x, y) of this episode's terrain."""
        return self.heightmap.max_height_near(x, y, _SPAWN_RADIUS)


def load_ground(
    client: BulletClient, terrain: FlatGround | HeightfieldTerrain
) -> PlaneGround | HeightfieldGround:
    """Build the ground a task's spec describes in a world."""
    if isinstance(terrain, FlatGround):
        return PlaneGround(client, terrain)
    return HeightfieldGround(client, terrain)

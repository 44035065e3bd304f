"""Loading ground into a bullet world."""

from __future__ import annotations

import os
import struct
import tempfile
import zlib

import numpy as np
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

    def show(self, heightmap: Heightmap) -> tuple[float, float, float]:
        """Replace the heights with `heightmap`'s, move the field to its place, and return
        that place (the field's centre, m)."""
        if heightmap.shape != self.grid_shape:
            raise ValueError(f"heightmap of shape {heightmap.shape}, expected {self.grid_shape}")
        low, high = self.height_bounds
        if heightmap.heights.min() < low - 1e-9 or heightmap.heights.max() > high + 1e-9:
            raise ValueError(f"heights outside the field's bounds {self.height_bounds}")
        # Bullet reads element i + j * rows as (x-index i, y-index j): column-major.
        self._heightfield(heightmap.heights.ravel(order="F").tolist(), replace=self.shape)
        center_x, center_y = heightmap.center
        place = (center_x, center_y, (low + high) / 2.0)
        self._client.resetBasePositionAndOrientation(self.body, place, (0.0, 0.0, 0.0, 1.0))
        return place


# Colours of the ground by height, low to high (RGB, 0-255): the shape shows in a frame.
_HEIGHT_COLOURS = np.array([(38, 84, 99), (96, 140, 80), (196, 178, 112), (240, 232, 214)])
_CHECKER = 0.5  # m: squares of alternating brightness, so motion shows too
_CHECKER_SHADE = 0.82  # brightness of the darker squares


def height_colours(heightmap: Heightmap) -> np.ndarray:
    """The texture that shows a heightmap: colour by height (from its lowest to its
    highest node), a 0.5 m checker, and a darker line every 2 cm of height. Image rows
    run along +y from the strip's near end and columns from +x to -x, as bullet lays a
    texture on a heightfield; shape (ny, nx, 3), uint8."""
    low, high = float(heightmap.heights.min()), float(heightmap.heights.max())
    level = (heightmap.heights - low) / (high - low) if high > low else heightmap.heights * 0.0
    stops = np.linspace(0.0, 1.0, len(_HEIGHT_COLOURS))
    rgb = np.stack(
        [np.interp(level, stops, _HEIGHT_COLOURS[:, channel]) for channel in range(3)], -1
    )
    xs, ys = heightmap.node_coordinates()
    squares = (np.floor(xs / _CHECKER)[:, None] + np.floor(ys / _CHECKER)[None, :]) % 2
    contour = np.floor(heightmap.heights / 0.02)
    edges = np.zeros(heightmap.shape, dtype=bool)
    edges[1:, :] |= contour[1:, :] != contour[:-1, :]
    edges[:, 1:] |= contour[:, 1:] != contour[:, :-1]
    shade = np.where(squares == 1, _CHECKER_SHADE, 1.0) * np.where(edges, 0.7, 1.0)
    image = (rgb * shade[:, :, None]).round().astype(np.uint8)
    return np.ascontiguousarray(image[::-1, :, :].transpose(1, 0, 2))


def _png(image: np.ndarray) -> bytes:
    """An RGB image as PNG bytes (the standard library suffices; pillow is optional)."""
    height, width, _ = image.shape
    raw = b"".join(b"\x00" + row.tobytes() for row in image)

    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data))

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(raw))
        + chunk(b"IEND", b"")
    )


# The bot's wheels span 0.12 m either side of its centre: spawn above the highest node there.
_SPAWN_RADIUS = 0.15  # m


class _Ground:
    """What both grounds share: their bodies' friction, scaled as a whole."""

    def _keep_friction(self, client: BulletClient, bodies: list[int], friction: float) -> None:
        self._client, self._bodies, self._friction = client, bodies, friction
        self._friction_factor = 1.0

    def set_friction(self, factor: float) -> None:
        """Every ground body's lateral friction `factor` times the task's (1: as built).
        Bullet multiplies the frictions of two bodies in contact: the wheels' grip on the
        ground scales by `factor` too."""
        if factor != self._friction_factor:
            for body in self._bodies:
                self._client.changeDynamics(body, -1, lateralFriction=self._friction * factor)
            self._friction_factor = factor


class BulletPlane(_Ground):
    """Flat ground in a world; the same every episode."""

    period = None  # nothing to follow the bot: the plane has no edge

    def __init__(self, client: BulletClient, terrain: FlatGround) -> None:
        self.body = add_ground_plane(client, terrain.friction)
        self._keep_friction(client, [self.body], terrain.friction)

    def reset(self, rng) -> float:
        """Nothing to draw: the spawn height is 0."""
        return 0.0

    def spawn_height(self, x: float, y: float) -> float:
        """Height (m) to set a bot's wheels at to stand at (x, y): 0."""
        return 0.0

    def heights_along(
        self,
        x: float,
        y: float,
        direction: tuple[float, float],
        offsets: tuple[float, ...],
        relative_to: float = 0.0,
    ) -> list[float]:
        """Ground heights (m) at (x, y) + offset * direction for each offset, less
        `relative_to`: the plane is at 0."""
        return [-relative_to] * len(offsets)

    def paint(self) -> None:
        """Nothing to paint: the plane is checkered already."""


# m: how far the flat ground around a terrain strip reaches; more than a bot can
# drive in an episode (15 s at the motors' 2.46 m/s top speed).
_SURROUND = 50.0
_SURROUND_DEPTH = 1.0  # m: the thickness of its boxes


def add_flat_surround(
    client: BulletClient,
    bounds: tuple[float, float, float, float],
    friction: float = GROUND_FRICTION,
    sides: bool = True,
) -> list[int]:
    """Flat ground at z = 0 around the rectangle `bounds`, as four static boxes (without
    `sides`: two, beyond the ends, as wide as the surround, for a field that moves
    along x).

    Boxes, not a plane under everything: a plane's pair with each wheel is
    checked every step (measured: 3-5% of a terrain step), a box's only when
    the bot is near it.
    """
    x_min, x_max, y_min, y_max = bounds
    far = _SURROUND
    if sides:
        pieces = [  # (x from, x to, y from, y to): left and right full length, then the ends
            (-far, x_min, -far, far),
            (x_max, far, -far, far),
            (x_min, x_max, -far, y_min),
            (x_min, x_max, y_max, far),
        ]
    else:
        pieces = [(-far, far, -far, y_min), (-far, far, y_max, far)]
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


class BulletHeightfield(_Ground):
    """Procedural ground in a world: a new heightmap each episode, flat ground around it."""

    def __init__(self, client: BulletClient, terrain: HeightfieldTerrain) -> None:
        self.terrain = terrain
        self.field = HeightfieldBody(
            client, terrain.grid_shape, terrain.cell_size, terrain.height_bounds
        )
        self.body = self.field.body
        self.period = terrain.lateral_period
        self.surround = add_flat_surround(client, terrain.bounds, sides=self.period is None)
        self._keep_friction(client, [self.body, *self.surround], GROUND_FRICTION)
        self.heightmap: Heightmap | None = None
        self._client = client
        self._texture: int | None = None
        self._painted: Heightmap | None = None
        self._center_x = 0.0  # where the field is centred along x now, m
        self._placed = (0.0, 0.0)  # the field's (y, z) position, m

    def reset(self, rng) -> float:
        """Draw this episode's terrain from `rng`, show it, and return the spawn height (m)."""
        self.heightmap = self.terrain.generate(rng)
        self._center_x, *self._placed = self.field.show(self.heightmap)
        return self.spawn_height(0.0, 0.0)

    def follow(self, x: float) -> None:
        """Keep a periodic field centred under a bot at `x` (m): when the bot is more than
        half a period from the middle, move the field by whole periods. The ground under
        the bot stays as it was; only the copy of the terrain it is on changes."""
        offset = x - self._center_x
        half = 0.5 * self.period
        if -half <= offset <= half:
            return
        self._center_x += round(offset / self.period) * self.period
        self._client.resetBasePositionAndOrientation(
            self.body, (self._center_x, *self._placed), (0.0, 0.0, 0.0, 1.0)
        )

    def spawn_height(self, x: float, y: float) -> float:
        """Height (m) to set a bot's wheels at to stand at (x, y) of this episode's terrain."""
        return self.heightmap.max_height_near(x, y, _SPAWN_RADIUS)

    def heights_along(
        self,
        x: float,
        y: float,
        direction: tuple[float, float],
        offsets: tuple[float, ...],
        relative_to: float = 0.0,
    ) -> list[float]:
        """Ground heights (m) at (x, y) + offset * direction for each offset (m), less
        `relative_to`, read from this episode's heightmap (0 on the flat ground around)."""
        return self.heightmap.heights_along(x, y, direction, offsets, relative_to)

    def paint(self) -> None:
        """Colour the ground by this episode's heights (`height_colours`), for rendering.

        Called before a frame is rendered, not on reset: training pays nothing for it.
        The texture is loaded once, from a PNG, and updated in place after that.
        """
        if self._painted is self.heightmap:
            return
        image = height_colours(self.heightmap)
        height, width, _ = image.shape
        if self._texture is None:
            with tempfile.TemporaryDirectory() as folder:
                path = os.path.join(folder, "ground.png")
                with open(path, "wb") as file:
                    file.write(_png(image))
                self._texture = self._client.loadTexture(path)
            self._client.changeVisualShape(
                self.body, -1, textureUniqueId=self._texture, rgbaColor=(1.0, 1.0, 1.0, 1.0)
            )
        else:
            self._client.changeTexture(self._texture, image.ravel().tolist(), width, height)
        self._painted = self.heightmap


def load_ground(
    client: BulletClient, terrain: FlatGround | HeightfieldTerrain
) -> BulletPlane | BulletHeightfield:
    """Build the ground a task's spec describes in a world."""
    if isinstance(terrain, FlatGround):
        return BulletPlane(client, terrain)
    return BulletHeightfield(client, terrain)

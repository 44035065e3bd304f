"""Loading ground into a bullet world."""

from __future__ import annotations

import os

import pybullet
import pybullet_data
from pybullet_utils.bullet_client import BulletClient

# Bullet multiplies the friction of the two bodies in contact: a ground of 1.0
# leaves each body's own friction (the bot's wheels: 0.8) as the contact's.
GROUND_FRICTION = 1.0

# A checkered, tiled plane: motion is visible in rendered frames.
_PLANE_MESH = os.path.join(pybullet_data.getDataPath(), "plane100.obj")


def add_ground_plane(client: BulletClient, friction: float = GROUND_FRICTION) -> int:
    """Add an infinite flat ground at z = 0 and return its body id."""
    collision = client.createCollisionShape(pybullet.GEOM_PLANE)
    visual = client.createVisualShape(pybullet.GEOM_MESH, fileName=_PLANE_MESH)
    ground = client.createMultiBody(
        baseMass=0.0, baseCollisionShapeIndex=collision, baseVisualShapeIndex=visual
    )
    client.changeDynamics(ground, -1, lateralFriction=friction)
    return ground

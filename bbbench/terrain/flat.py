"""Flat ground."""

from __future__ import annotations

from bbbench.parameters import parameters

GROUND_FRICTION = 1.0  # Bullet multiplies frictions: the wheels' 0.8 is the contact's


@parameters
class FlatGround:
    """An infinite plane at z = 0."""

    friction: float = GROUND_FRICTION

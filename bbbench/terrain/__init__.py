"""Ground for the robots to stand on.

Flat ground for now. Procedural terrain arrives as pure-numpy heightmap
generators, with conversion to meshes and loading into a bullet world kept in
small modules of their own. Nothing here knows about robots.
"""

from bbbench.terrain.bullet import GROUND_FRICTION, add_ground_plane
from bbbench.terrain.flat import FlatGround

__all__ = ["GROUND_FRICTION", "FlatGround", "add_ground_plane"]

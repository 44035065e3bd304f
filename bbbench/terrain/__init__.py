"""Ground for the robots to stand on.

- `generators`: seeded, pure-numpy heightmap generators with a difficulty;
- `heightmap`: `Heightmap` and `HeightfieldTerrain`, a generator placed as a strip;
- `mesh`: heightmaps as trimesh meshes, exported for inspection;
- `bullet`: loading ground into a bullet world (plane or heightfield).

Nothing here knows about robots.
"""

from bbbench.terrain.bullet import add_ground_plane, load_ground
from bbbench.terrain.flat import GROUND_FRICTION, FlatGround
from bbbench.terrain.generators import GENERATORS, Bumps, Level, ObstacleCourse, Obstacles, Slopes
from bbbench.terrain.heightmap import HeightfieldTerrain, Heightmap

__all__ = [
    "GENERATORS",
    "GROUND_FRICTION",
    "Bumps",
    "FlatGround",
    "HeightfieldTerrain",
    "Heightmap",
    "Level",
    "ObstacleCourse",
    "Obstacles",
    "Slopes",
    "add_ground_plane",
    "load_ground",
]

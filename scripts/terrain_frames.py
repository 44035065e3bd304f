"""Write the README's frame of each -v1 terrain task (docs/images/*.png).

    python scripts/terrain_frames.py   # needs pillow: pip install 'bbbench[video]'

Each frame is the env's own `rgb_array` render, 1.5 s into the first
evaluation seed with the PD baseline driving.
"""

from __future__ import annotations

from pathlib import Path

from PIL import Image

import bbbench
from bbbench.policies import PDController

TASKS = ("bbbench/Bumps-v1", "bbbench/Obstacles-v1", "bbbench/Slopes-v1")
OUT = Path(__file__).resolve().parent.parent / "docs" / "images"


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for task_id in TASKS:
        env, policy = bbbench.make(task_id, render_mode="rgb_array"), PDController()
        observation, _ = env.reset(seed=bbbench.spec(task_id).eval_seeds[0])
        for _ in range(150):
            observation, *_ = env.step(policy(observation))
        path = OUT / f"{task_id.split('/')[1].lower()}.png"
        Image.fromarray(env.render()).save(path, optimize=True)
        env.close()
        print(f"wrote {path}")


if __name__ == "__main__":
    main()

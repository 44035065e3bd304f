"""Write the README's frame of each terrain task (docs/images/*.png).

    python scripts/terrain_frames.py   # needs pillow: pip install 'bbbench[video]'

Each frame is the env's own `rgb_array` render, 1.5 s into the first evaluation seed
with the robot's classical controller driving (PD; the wheel-legged robot's own).

Also the README's GIF (docs/images/legged-bumps.gif): the legged controller's first
LeggedBumps-v0 evaluation episode as `bbbench eval legged --video` writes it (15 s, 10 MB),
cut to its first 10 s, every other frame, 240 x 180 and 64 colours (under 2 MB).
"""

from __future__ import annotations

import subprocess
import tempfile
from pathlib import Path

from PIL import Image

import bbbench
from bbbench.policies import PDController
from bbbench.policies.legged import LeggedController

TASKS = (
    "bbbench/Bumps-v1",
    "bbbench/Obstacles-v1",
    "bbbench/Slopes-v1",
    "bbbench/LeggedFlatBalance-v0",
    "bbbench/LeggedVelocityTracking-v0",
    "bbbench/LeggedBumps-v0",
    "bbbench/LeggedObstacles-v0",
)
OUT = Path(__file__).resolve().parent.parent / "docs" / "images"


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for task_id in TASKS:
        legged = bbbench.spec(task_id).robot == "wheel-legged"
        policy = LeggedController() if legged else PDController()
        env = bbbench.make(task_id, render_mode="rgb_array")
        observation, _ = env.reset(seed=bbbench.spec(task_id).eval_seeds[0])
        for _ in range(150):
            observation, *_ = env.step(policy(observation))
        path = OUT / f"{task_id.split('/')[1].lower()}.png"
        Image.fromarray(env.render()).save(path, optimize=True)
        env.close()
        print(f"wrote {path}")


def legged_gif() -> None:
    with tempfile.TemporaryDirectory() as folder:
        full = Path(folder) / "full.gif"
        subprocess.run(
            ["bbbench", "eval", "legged", "--task", "bbbench/LeggedBumps-v0", "--episodes", "1",
             "--workers", "1", "--video", str(full)],
            check=True, stdout=subprocess.DEVNULL,
        )  # fmt: skip
        episode, frames = Image.open(full), []
        for index in range(0, min(episode.n_frames, 250), 2):  # 10 s at 25 frames per second
            episode.seek(index)
            frame = episode.convert("RGB").resize((240, 180), Image.BILINEAR)
            frames.append(frame.quantize(colors=64, method=Image.Quantize.MEDIANCUT))
    path = OUT / "legged-bumps.gif"
    frames[0].save(path, save_all=True, append_images=frames[1:], duration=80, loop=0)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
    legged_gif()

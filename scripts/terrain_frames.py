"""Write the frame of each task for the README and the site's task pages
(docs/images/*.png), and their GIFs.

    python scripts/terrain_frames.py [--teams | --steering | --balance | --talk]
    # needs bbbench[video]

Each frame is the env's own `rgb_array` render, 1.5 s into the first evaluation seed
with the robot's classical controller driving (PD; the wheel-legged robot's own; the
team controller on the team tasks, whose frame is the whole team).

Also the README's GIFs, each an evaluation episode as `bbbench eval POLICY --video`
writes it (15 s, about 10 MB), cut to its first 10 s, every other frame, 240 x 180 and 64
colours (under 2 MB): the legged controller's first LeggedBumps-v0 episode
(docs/images/legged-bumps.gif), and the team controller carrying the beam over the hills
of BeamCarryBumps-v0 (docs/images/beamcarry-bumps.gif). `--teams`: the team tasks' frames
and GIF only. `--steering`: the steering robot's tasks, each driven by its built-in
controller (steer, steer-avoid on Swap, team on ConvoyTurns; on Swap 2 s in, as the bots
meet), and the GIF of steer-avoid's bots passing each other on Swap-v0
(docs/images/swap.gif). `--balance`: the flat, pushed and crossing tasks (PD; the
crossing controller on the multi-bot ones), and the GIF of the crossing controller's bots
on MultiBalance-v1 (docs/images/multibalance.gif). `--talk`: the tasks with a message
channel (Rendezvous, the rendezvous controller driving; its landmarks drawn, the goal red).
`--mixed`: the mixed team's tasks, the mixed-team controller driving.
"""

from __future__ import annotations

import argparse
import subprocess
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

import bbbench
from bbbench.policies import classical_controller, load_policy
from bbbench.policies.controllers.team import TeamController

TASKS = (
    "bbbench/Bumps-v1",
    "bbbench/Obstacles-v1",
    "bbbench/Slopes-v1",
    "bbbench/LeggedFlatBalance-v0",
    "bbbench/LeggedVelocityTracking-v0",
    "bbbench/LeggedBumps-v0",
    "bbbench/LeggedObstacles-v0",
)
TEAM_TASKS = ("bbbench/BeamCarry-v0", "bbbench/BeamCarryBumps-v0", "bbbench/Convoy-v0")
OUT = Path(__file__).resolve().parent.parent / "docs" / "images"


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for task_id in TASKS:
        policy = load_policy(classical_controller(task_id))
        actor = policy.actor(task_id)
        env = bbbench.make(task_id, render_mode="rgb_array", action_mode=policy.action_mode)
        observation, _ = env.reset(seed=bbbench.spec(task_id).eval_seeds[0])
        for _ in range(150):
            observation, *_ = env.step(actor(observation[None])[0])
        path = OUT / f"{task_id.split('/')[1].lower()}.png"
        Image.fromarray(env.render()).save(path, optimize=True)
        env.close()
        print(f"wrote {path}")


def team_frames() -> None:
    for task_id in TEAM_TASKS:
        env = bbbench.make_parallel(task_id, render_mode="rgb_array")
        team = TeamController.for_scenario(env.scene.scenario)
        observations, _ = env.reset(seed=bbbench.spec(task_id).eval_seeds[0])
        for _ in range(150):
            observations, *_ = env.step({a: team(observations[a]) for a in env.agents})
        path = OUT / f"{task_id.split('/')[1].lower()}.png"
        Image.fromarray(env.render()).save(path, optimize=True)
        env.close()
        print(f"wrote {path}")


STEERING = {
    "bbbench/SteerTracking-v0": "steer",
    "bbbench/Waypoints-v0": "steer",
    "bbbench/WaypointsBumps-v0": "steer",
    "bbbench/Swap-v0": "steer-avoid",
    "bbbench/ConvoyTurns-v0": "team",
}


# The tasks with a message channel, each with its classical controller.
TALK = {"bbbench/Rendezvous-v0": "rendezvous"}

# The mixed team's tasks, the mixed team's controller driving.
MIXED = {"bbbench/MixedBeamCarry-v0": "mixed-team", "bbbench/MixedBeamCarryBumps-v0": "mixed-team"}


# The balance and crossing tasks (the site's task pages): each with its classical controller.
BALANCE = {
    "bbbench/FlatBalance-v1": "pd",
    "bbbench/VelocityTracking-v1": "pd",
    "bbbench/NoisySensors-v1": "pd",
    "bbbench/PushRecovery-v0": "pd",
    "bbbench/MultiBalance-v1": "crossing",
    "bbbench/MultiBumps-v1": "crossing",
}


def frames(tasks: dict[str, str]) -> None:
    """A frame of each task, with its policy (a built-in's name) driving."""
    for task_id, name in tasks.items():
        actor = load_policy(name).actor(task_id)
        multi = bbbench.spec(task_id).multi_agent
        env = (bbbench.make_parallel if multi else bbbench.make)(task_id, render_mode="rgb_array")
        observations, _ = env.reset(seed=bbbench.spec(task_id).eval_seeds[0])
        for _ in range(200 if name == "steer-avoid" else 150):
            if multi:
                rows = [observations[a] for a in env.agents]
                if env.task.mixed:  # each robot's bots through its own actor
                    actions = actor.team(rows, [env.agent_index[a] for a in env.agents])
                else:
                    actions = actor(np.stack(rows))
                observations, *_ = env.step(dict(zip(env.agents, actions, strict=True)))
            else:
                observations, *_ = env.step(actor(observations[None])[0])
        path = OUT / f"{task_id.split('/')[1].lower()}.png"
        Image.fromarray(env.render()).save(path, optimize=True)
        env.close()
        print(f"wrote {path}")


def gif(policy: str, task_id: str, name: str) -> None:
    """`policy`'s first evaluation episode of `task_id`, shrunk, as docs/images/`name`."""
    with tempfile.TemporaryDirectory() as folder:
        full = Path(folder) / "full.gif"
        subprocess.run(
            ["bbbench", "eval", policy, "--task", task_id, "--episodes", "1",
             "--workers", "1", "--video", str(full)],
            check=True, stdout=subprocess.DEVNULL,
        )  # fmt: skip
        episode, frames = Image.open(full), []
        for index in range(0, min(episode.n_frames, 250), 2):  # 10 s at 25 frames per second
            episode.seek(index)
            frame = episode.convert("RGB").resize((240, 180), Image.BILINEAR)
            frames.append(frame.quantize(colors=64, method=Image.Quantize.MEDIANCUT))
    path = OUT / name
    frames[0].save(path, save_all=True, append_images=frames[1:], duration=80, loop=0)
    print(f"wrote {path}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    only = parser.add_mutually_exclusive_group()
    only.add_argument("--teams", action="store_true", help="the team tasks only")
    only.add_argument("--steering", action="store_true", help="the steering tasks only")
    only.add_argument("--balance", action="store_true", help="the balance and crossing tasks")
    only.add_argument("--talk", action="store_true", help="the tasks with a message channel")
    only.add_argument("--mixed", action="store_true", help="the mixed team's tasks")
    args = parser.parse_args()
    everything = not (args.teams or args.steering or args.balance or args.talk or args.mixed)
    if everything:
        main()
        gif("legged", "bbbench/LeggedBumps-v0", "legged-bumps.gif")
    if everything or args.teams:
        team_frames()
        gif("team", "bbbench/BeamCarryBumps-v0", "beamcarry-bumps.gif")
    if everything or args.steering:
        frames(STEERING)
        gif("steer-avoid", "bbbench/Swap-v0", "swap.gif")
    if everything or args.balance:
        frames(BALANCE)
        gif("crossing", "bbbench/MultiBalance-v1", "multibalance.gif")
    if everything or args.talk:
        frames(TALK)
    if everything or args.mixed:
        frames(MIXED)

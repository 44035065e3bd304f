"""One evaluation episode as a GIF or MP4, through the env's `rgb_array` render."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bbbench.envs.factory import make, make_parallel
from bbbench.evaluation.episodes import action_generator
from bbbench.evaluation.play import Lockstep, MultiEpisode
from bbbench.files import check_output_path, replacing
from bbbench.policies.policy import Policy
from bbbench.tasks.suite import spec

VIDEO_FORMATS = (".gif", ".mp4")
FRAME_EVERY = 4  # steps per frame: 25 frames per second of a 100 Hz task


def check_video_path(path: str | Path) -> Path:
    """`ValueError` unless the path ends in .gif or .mp4, can be written (an existing,
    writable directory; not a directory itself), and a writer for it is installed."""
    path = check_output_path(path, "--video")
    if path.suffix.lower() not in VIDEO_FORMATS:
        raise ValueError(f"--video {path}: expected a file name ending in .gif or .mp4")
    try:
        # lazy: imageio, for --video only
        import imageio.v3  # noqa: F401

        if path.suffix.lower() == ".mp4":
            # lazy: imageio_ffmpeg, for .mp4 only
            import imageio_ffmpeg  # noqa: F401
    except ImportError:
        raise ValueError(
            f"--video {path}: writing video needs imageio; pip install 'bbbench[video]'"
        ) from None
    return path


def record_episode(
    policy: Policy, task_id: str, seed: int, path: str | Path, stochastic: bool = False
) -> int:
    """Play episode `seed` of `task_id`, write its frames to `path` (atomically), and
    return the number of frames. The episode is played alone; the evaluation plays it
    in a lockstep group, so a network's outputs (and so continuous actions) can differ
    from the evaluated episode's in their last bits."""
    import imageio.v3 as iio  # lazy: imageio, for --video only

    path = check_video_path(path)
    task = spec(task_id)
    act = policy.acting(task_id, stochastic)
    rng = action_generator(seed) if stochastic or policy.random_actions else None
    frames = []
    _play(task, policy, act, rng, seed, frames)
    fps = round(1.0 / (task.control_dt * FRAME_EVERY))
    with replacing(path, suffix=path.suffix) as temporary:
        if path.suffix.lower() == ".gif":
            iio.imwrite(temporary, np.stack(frames), duration=1000 / fps, loop=0)
        else:
            iio.imwrite(temporary, np.stack(frames), fps=fps, codec="libx264", macro_block_size=8)
    return len(frames)


def _play(task, policy: Policy, act, rng, seed: int, frames: list[np.ndarray]) -> None:
    """Play the episode, keeping every FRAME_EVERY-th frame and the last."""
    mode = policy.action_mode
    if task.multi_agent:
        env = make_parallel(task.id, action_mode=mode, render_mode="rgb_array")
        steps = (played.step for played in MultiEpisode(env, act, seed, rng) if env.agents)
    else:
        env = make(task.id, action_mode=mode, render_mode="rgb_array", **policy.env_options())
        rngs = None if rng is None else [rng]
        played = Lockstep([env], act, [seed], rngs=rngs)
        steps = (step.step for step in played if not step.ended)
    last = task.max_episode_steps - 1  # a time limit's last step, bots still in the world
    try:
        for step in steps:
            if step % FRAME_EVERY == 0 or (task.multi_agent and step == last):
                frames.append(env.render())
    finally:
        # the world as the episode left it; on a multi-bot task whose bots leave the world
        # as they end (not a team's), that is an empty world: the last frame with bots stands
        if not task.multi_agent or env.agents or task.scenario_class.team:
            frames.append(env.render())
        env.close()

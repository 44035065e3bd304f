"""Golden rollouts: each task version's behaviour, pinned by hashes stored in the repo.

A task ID's fingerprint hashes its spec together with the hash of a golden
rollout: for each of `GOLDEN_SEEDS`, what the seed generated (the whole target
schedule, sensor errors and terrain), then the observations and rewards of the
fixed action sequence `golden_actions()`, all rounded to `DECIMALS` places. tests/test_versions.py
recomputes both for every registered ID and fails when either differs from
`golden.json`: a behaviour change needs a new version (`-v1`), and the old one
stays registered.

    bbbench dev golden           # print the hashes as they are now
    bbbench dev golden --add     # store the IDs golden.json lacks
"""

from __future__ import annotations

import hashlib
import json

import numpy as np
from gymnasium import spaces

from bbbench.envs.balance import BalanceEnv
from bbbench.envs.episode import EpisodeDraw
from bbbench.envs.multi import MultiBalanceEnv
from bbbench.evaluation.play import Lockstep, MultiEpisode
from bbbench.files import write_atomic
from bbbench.robots import TWO_WHEEL, Robot
from bbbench.tasks.spec import GOLDEN_FILE, TaskSpec
from bbbench.tasks.suite import list_tasks, spec

GOLDEN_SEEDS = (2**31, 2**31 + 1)  # two evaluation seeds
GOLDEN_STEPS = 200  # per seed, or until the episode ends
DECIMALS = 4  # observations and rewards are rounded to 1e-4 before hashing


def golden_actions(robot: Robot = TWO_WHEEL, action_mode: str | None = None) -> list:
    """The fixed action sequence of every golden rollout of `robot`'s tasks, in its default
    action mode (or `action_mode`: a mixed team's): uniform draws from its action space
    (for the two-wheel bot, discrete indices 0-8)."""
    space = robot.action_space(action_mode or robot.default_action_mode)
    rng = np.random.default_rng(0)
    if isinstance(space, spaces.Discrete):
        return [int(a) for a in rng.integers(0, space.n, size=GOLDEN_STEPS)]
    draws = rng.uniform(space.low, space.high, size=(GOLDEN_STEPS, *space.shape))
    return list(draws.astype(space.dtype))


def rollout_hash(task: TaskSpec) -> str:
    """Hash of the task's golden rollout (its robot's default action mode, the spec as
    given)."""
    if task.multi_agent:
        return _multi_rollout_hash(task)
    env = BalanceEnv(task)
    actions = golden_actions(task.robot_model)

    def act(batch, rngs) -> list:  # step t: the t-th action
        return [actions[env.scene.steps]]

    digest = hashlib.sha256()
    for seed in GOLDEN_SEEDS:
        values = []
        for step in Lockstep([env], act, [seed], GOLDEN_STEPS):
            if step.rewards is None:  # reset
                # What the seed generated, whole: a short rollout can fall on the level
                # start pad before the terrain, a later target or the noise ever shows.
                values += [*_generated(env.scene.episode), step.observations[0].copy()]
            else:
                values.append(np.append(step.observations[0], step.rewards[0]))
        rounded = np.round(np.concatenate(values).astype(np.float64), DECIMALS) + 0.0  # no -0.0
        digest.update(rounded.tobytes())
    env.close()
    return digest.hexdigest()[:16]


def _multi_rollout_hash(task: TaskSpec) -> str:
    """The same for a multi-bot task: bot j plays the fixed sequence shifted by j steps (on
    a mixed team, its robot's sequence in the task's action mode)."""
    env = MultiBalanceEnv(task)
    robots = [model.name for model in task.bot_robots] if task.mixed else None
    sequences = (
        {model.name: golden_actions(model, env.action_mode) for model in task.bot_robots}
        if robots
        else {}
    )
    actions = golden_actions()

    def of(bots: list[int]) -> list:  # step t: the actions of the live `bots`, in order
        t = env.scene.steps
        if robots is None:
            return [actions[(t + j) % GOLDEN_STEPS] for j in bots]
        return [sequences[robots[j]][(t + j) % GOLDEN_STEPS] for j in bots]

    def act(batch, rngs) -> list:
        return of([env.agent_index[a] for a in env.agents])

    act.team = lambda rows, bots, rngs: of(bots)  # a mixed team's (`TeamActor.team`)

    digest = hashlib.sha256()
    for seed in GOLDEN_SEEDS:
        values = []
        for step in MultiEpisode(env, act, seed):
            if step.rewards is None:  # reset
                values += [*_generated(env.scene.episode), *step.observations.values()]
            else:
                values.extend(
                    np.append(step.observations[a], step.rewards[a]) for a in step.observations
                )
            if step.step == GOLDEN_STEPS:
                break
        rounded = np.round(np.concatenate(values).astype(np.float64), DECIMALS) + 0.0
        digest.update(rounded.tobytes())
    env.close()
    return digest.hexdigest()[:16]


def _generated(episode: EpisodeDraw) -> list[np.ndarray]:
    """What an episode's seed drew, as the golden hash takes it: targets (bot by bot),
    sensor errors, terrain heights, and the pushes (step, bot, impulse) when there are any
    (a short rollout falls before the first)."""
    values = [episode.targets.ravel()]
    if episode.sensor_errors is not None:
        values.append(episode.sensor_errors.ravel())
    if episode.heightmap is not None:
        values.append(episode.heightmap.heights.ravel())
    if episode.pushes:
        values.append(np.array(episode.pushes, dtype=np.float64).ravel())
    return values


def load() -> dict[str, dict[str, str]]:
    """The stored hashes: {task id: {"spec": ..., "rollout": ...}}."""
    return json.loads(GOLDEN_FILE.read_text()) if GOLDEN_FILE.exists() else {}


def current(task_ids) -> dict[str, dict[str, str]]:
    return {
        task_id: {"spec": spec(task_id).spec_hash, "rollout": rollout_hash(spec(task_id))}
        for task_id in task_ids
    }


def report(add: bool = False) -> list[str]:
    """Each registered ID's hashes as they are now, against the stored ones ("ok", "NEW" or
    "CHANGED"); with `add`, store the IDs golden.json lacks (never changing one)."""
    stored, now = load(), current(list_tasks())
    lines = []
    for task_id, hashes in now.items():
        state = (
            "ok" if stored.get(task_id) == hashes else "NEW" if task_id not in stored else "CHANGED"
        )
        lines.append(f"{task_id:30s} spec {hashes['spec']} rollout {hashes['rollout']}  {state}")
    if add:
        merged = {**now, **stored}  # an existing ID's hashes are never overwritten
        text = json.dumps(dict(sorted(merged.items())), indent=2) + "\n"
        write_atomic(GOLDEN_FILE, text.encode())
    return lines

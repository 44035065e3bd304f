"""Versions cannot drift: every registered ID still behaves as its stored golden rollout."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import bbbench
from bbbench.dev import golden
from bbbench.evaluation import evaluate
from bbbench.policies import load_policy
from bbbench.terrain import Bumps
from conftest import REWARD_SUCCESSORS

STORED = golden.load()


def test_every_registered_task_is_pinned_and_every_pinned_task_stays_registered():
    assert set(bbbench.list_tasks()) <= set(STORED), "run: bbbench dev golden --add"
    for task_id in STORED:  # an old version stays registered when a new one is added
        assert task_id in bbbench.tasks.SUITE
        assert task_id in gym.registry  # a multi-bot ID too: gym.make says what to use


@pytest.mark.parametrize("task_id", ["bbbench/MultiBalance-v0", "bbbench/MultiBumps-v0"])
def test_gymnasium_make_of_a_multi_bot_task_points_to_make_parallel(task_id):
    with pytest.raises(ValueError, match=r"bbbench\.make_parallel") as raised:
        gym.make(task_id)
    with pytest.raises(ValueError, match="multi-bot") as from_bbbench:
        bbbench.make(task_id)
    assert str(raised.value) == str(from_bbbench.value)


@pytest.mark.parametrize("task_id", sorted(STORED))
def test_behaviour_matches_the_golden_rollout(task_id):
    spec = bbbench.spec(task_id)
    now = {"spec": spec.spec_hash, "rollout": golden.rollout_hash(spec)}
    assert now == STORED[task_id], (
        f"{task_id} changed (stored {STORED[task_id]}, now {now}) while its version did not: "
        f"register the new behaviour as a new version (-v1), keep {task_id} as it was, "
        f"and add the new ID with `bbbench dev golden --add`"
    )


def test_the_golden_rollout_notices_changes_to_any_part():
    spec = bbbench.spec("bbbench/Bumps-v0")
    stored = STORED[spec.id]["rollout"]
    changed_start = dataclasses.replace(spec, initial_pitch=0.05)
    changed_terrain = dataclasses.replace(
        spec, terrain=dataclasses.replace(spec.terrain, generator=Bumps(min_height=0.03))
    )
    for variant in (changed_start, changed_terrain):
        assert golden.rollout_hash(variant) != stored
        assert variant.fingerprint != spec.fingerprint


def test_physics_changes_are_noticed(monkeypatch):
    import bbbench.sim

    monkeypatch.setattr(bbbench.sim, "SOLVER_ITERATIONS", 50)
    spec = bbbench.spec("bbbench/FlatBalance-v0")
    assert golden.rollout_hash(spec) != STORED[spec.id]["rollout"]


def test_fingerprints_tell_the_tasks_apart():
    fingerprints = {bbbench.spec(task_id).fingerprint for task_id in bbbench.list_tasks()}
    assert len(fingerprints) == len(bbbench.list_tasks())


# A new version changes only the reward: the same seed and actions play the same episode.
SINGLE_SUCCESSORS = {
    new: old for new, old in REWARD_SUCCESSORS.items() if not bbbench.spec(new).multi_agent
}
MULTI_SUCCESSORS = {
    new: old for new, old in REWARD_SUCCESSORS.items() if bbbench.spec(new).multi_agent
}


def _episode(env, seed: int, actions) -> tuple[list, list, list]:
    observation, _ = env.reset(seed=seed)
    observations, terminations, rewards = [observation], [], []
    for action in actions:
        observation, reward, terminated, truncated, _ = env.step(action)
        observations.append(observation)
        terminations.append(terminated)
        rewards.append(reward)
        if terminated or truncated:
            break
    return observations, terminations, rewards


@pytest.mark.parametrize(("new", "old"), SINGLE_SUCCESSORS.items())
def test_a_new_reward_version_observes_and_terminates_as_its_predecessor(new, old):
    actions = [int(a) for a in np.random.default_rng(3).integers(0, 9, size=600)]
    # A wheel held fast, then random changes: a long episode, then a fall.
    actions = [4] * 20 + [5] * 200 + actions
    for seed in (bbbench.spec(new).eval_seeds[0], 12):
        new_run, old_run = (_episode(gym.make(task), seed, actions) for task in (new, old))
        assert len(new_run[0]) == len(old_run[0])
        assert all(np.array_equal(a, b) for a, b in zip(new_run[0], old_run[0], strict=True))
        assert new_run[1] == old_run[1]
        assert new_run[2] != old_run[2]  # and the reward is not the same


@pytest.mark.parametrize(("new", "old"), MULTI_SUCCESSORS.items())
def test_a_new_multi_bot_version_observes_and_terminates_as_its_predecessor(new, old):
    rng = np.random.default_rng(5)
    runs = []
    for task in (new, old):
        env = bbbench.make_parallel(task)
        observations, _ = env.reset(seed=21)
        record = [observations]
        actions = rng.integers(0, 9, size=(300, env.max_num_agents))
        rng = np.random.default_rng(5)  # the same actions for both versions
        for row in actions:
            if not env.agents:
                break
            step = {agent: int(row[env.agent_index[agent]]) for agent in env.agents}
            observations, _, terminations, truncations, _ = env.step(step)
            record += [observations, terminations, truncations]
        runs.append(record)
    new_run, old_run = runs
    assert len(new_run) == len(old_run)
    for a, b in zip(new_run, old_run, strict=True):
        assert a.keys() == b.keys()
        assert all(np.array_equal(a[agent], b[agent]) for agent in a)


# PD's episodes as published on every ID before the reward's new versions: the first 8
# evaluation episodes of each, from the board's results document of that time (one
# MultiBumps-v0 episode corrected to what its seed plays in a fresh world: the file's
# "source" says why).
PUBLISHED_PD = json.loads((Path(__file__).parent / "data" / "pd_published.json").read_text())


@pytest.mark.parametrize("task_id", sorted(PUBLISHED_PD["episodes"]))
def test_pd_plays_every_published_id_exactly_as_published(task_id):
    stored = PUBLISHED_PD["episodes"][task_id]
    document = evaluate(load_policy("pd"), [task_id], episodes=len(stored), workers=1).document
    assert document["tasks"][0]["episodes"] == stored


def test_gymnasium_make_of_a_version_that_does_not_exist_names_the_ones_that_do():
    with pytest.raises(gym.error.VersionNotFound, match=r"v0.*v1"):
        gym.make("bbbench/FlatBalance-v7")

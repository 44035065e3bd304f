"""Versions cannot drift: every registered ID still behaves as its stored golden rollout."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import pytest

import bbbench
from bbbench.tasks import golden
from bbbench.terrain import Bumps

STORED = golden.load()


def test_every_registered_task_is_pinned_and_every_pinned_task_stays_registered():
    assert set(bbbench.list_tasks()) <= set(STORED), "run: python -m bbbench.tasks.golden --add"
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
        f"and add the new ID with `python -m bbbench.tasks.golden --add`"
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

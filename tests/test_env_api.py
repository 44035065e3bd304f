"""FlatBalance-v0 through gymnasium: registration, checkers, spaces, errors, rendering."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import bbbench
from bbbench.envs.balance import RENDER_HEIGHT, RENDER_WIDTH
from conftest import FLAT


def test_both_make_forms_give_the_registered_task():
    plain = gym.make(FLAT)
    namespaced = gym.make("bbbench:bbbench/FlatBalance-v0")
    assert plain.spec.id == namespaced.spec.id == FLAT
    assert plain.spec.max_episode_steps == 1500
    assert bbbench.make(FLAT).spec.max_episode_steps == 1500


def test_spaces_are_the_documented_ones(flat_env, action_mode):
    assert flat_env.observation_space.shape == (5,)
    assert flat_env.observation_space.dtype == np.float32
    if action_mode == "discrete":
        assert flat_env.action_space == gym.spaces.Discrete(9)
    else:
        assert flat_env.action_space == gym.spaces.Box(-1.0, 1.0, (1,), np.float32)


def test_spec_api():
    spec = bbbench.spec(FLAT)
    assert spec.id == FLAT
    assert spec.max_episode_steps == 1500
    assert len(spec.eval_seeds) >= 100
    assert len(spec.fingerprint) == 16
    assert spec.max_return == pytest.approx(150.0)
    assert FLAT in bbbench.list_tasks()
    with pytest.raises(AttributeError):
        spec.max_episode_steps = 10  # frozen


def test_fingerprint_changes_with_behaviour_not_with_documentation():
    import dataclasses

    spec = bbbench.spec(FLAT)
    assert dataclasses.replace(spec, summary="reworded").fingerprint == spec.fingerprint
    assert dataclasses.replace(spec, initial_pitch=0.05).fingerprint != spec.fingerprint


def test_unknown_task_names_the_closest():
    with pytest.raises(ValueError, match=r"FlatBalance-v0.*Known tasks"):
        bbbench.spec("FlatBalance-v0")
    with pytest.raises(ValueError, match="Did you mean 'bbbench/FlatBalance-v0'"):
        bbbench.make("bbbench/FlatBalanse-v0")


def test_unknown_keyword_lists_the_accepted_ones():
    with pytest.raises(TypeError, match=r"\['speed'\].*action_mode.*render_mode"):
        gym.make(FLAT, speed=3)
    with pytest.raises(ValueError, match="action_mode must be one of"):
        gym.make(FLAT, action_mode="analog")


@pytest.mark.parametrize("bad", [9, -1, 2.0, "3", None, np.array([1, 2])])
def test_discrete_action_outside_the_space_is_refused(bad):
    env = gym.make(FLAT)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"not in the action space.*0\.\.8"):
        env.step(bad)


@pytest.mark.parametrize(
    "bad", [np.array([np.nan], np.float32), np.array([1.5], np.float32), [-2.0], "x", [0.1, 0.2]]
)
def test_continuous_action_outside_the_space_or_nan_is_refused(bad):
    env = gym.make(FLAT, action_mode="continuous")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"not in the action space.*\[-1, 1\]"):
        env.step(bad)


def test_in_space_actions_of_every_form_are_accepted():
    env = gym.make(FLAT)
    env.reset(seed=0)
    for action in (0, np.int64(8), np.array(4)):
        env.step(action)
    env = gym.make(FLAT, action_mode="continuous")
    env.reset(seed=0)
    for action in (np.array([1.0], np.float32), [-1.0], np.array([0.25])):
        env.step(action)


def test_step_before_reset_is_a_clear_error():
    env = bbbench.envs.balance.BalanceEnv()
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(4)


def test_world_is_created_on_first_reset_only():
    env = gym.make(FLAT)
    assert not env.unwrapped.scene.world.connected
    env.reset(seed=0)
    assert env.unwrapped.scene.world.connected
    env.close()
    assert not env.unwrapped.scene.world.connected
    observation, _ = env.reset(seed=0)  # a closed env builds a new world when reset
    assert env.observation_space.contains(observation)


def test_rgb_array_renders_frames_that_follow_the_bot():
    env = gym.make(FLAT, render_mode="rgb_array")
    env.reset(seed=0)
    first = env.render()
    assert first.shape == (RENDER_HEIGHT, RENDER_WIDTH, 3)
    assert first.dtype == np.uint8
    assert first.std() > 10  # a picture, not a blank frame
    for _ in range(40):
        env.step(8)  # accelerate forward: the bot moves and tilts
    assert not np.array_equal(env.render(), first)


def test_render_without_a_mode_warns_and_returns_none():
    env = gym.make(FLAT)
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.render() is None


def test_reset_takes_no_options():
    env = gym.make(FLAT)
    with pytest.raises(ValueError, match="no options"):
        env.reset(seed=0, options={"difficulty": 1})

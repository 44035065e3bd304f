"""The time limit is decided once, by the scene (`Scene.truncated`): the single-bot env
returns it with or without Gymnasium's `TimeLimit`, the multi-bot env truncates its
agents on it, and the play loops end episodes on the env's word, not a count of their
own."""

from __future__ import annotations

import gymnasium
import pytest

import bbbench
from bbbench.envs.balance import BalanceEnv
from bbbench.evaluation.play import Lockstep, MultiEpisode
from bbbench.policies import load_policy

FLAT = "bbbench/FlatBalance-v1"


def steps_to_end(env, seed: int = 0) -> tuple[int, bool, bool]:
    """PD's steps until the env ends the episode, and how (terminated, truncated); at
    most 5000 (an env that never truncates: (5000, False, False))."""
    act = load_policy("pd").actor(FLAT)
    observation, _ = env.reset(seed=seed)
    steps = 0
    terminated = truncated = False
    while not (terminated or truncated) and steps < 5000:
        observation, _, terminated, truncated, _ = env.step(act(observation[None], None)[0])
        steps += 1
    return steps, terminated, truncated


def test_the_env_itself_truncates_at_its_tasks_limit():
    env = BalanceEnv(FLAT)  # no TimeLimit wrapper
    assert steps_to_end(env) == (1500, False, True)


@pytest.mark.parametrize(
    ("make", "steps"),
    [
        (lambda: gymnasium.make(FLAT), 1500),
        (lambda: gymnasium.make(FLAT, max_episode_steps=40), 40),  # its wrapper, sooner
        (lambda: bbbench.make(FLAT, max_episode_steps=40), 40),
        (lambda: bbbench.make(FLAT, max_episode_steps=1600), 1600),  # the env's own, later
    ],
)
def test_made_envs_end_where_their_limit_says(make, steps):
    env = make()
    assert steps_to_end(env) == (steps, False, True)
    assert env.spec.max_episode_steps == steps


def test_bbbench_make_refuses_a_limit_that_is_not_a_number_of_steps():
    with pytest.raises(ValueError, match="max_episode_steps must be a whole number of steps"):
        bbbench.make(FLAT, max_episode_steps=0)


def test_the_play_loops_end_episodes_where_the_env_says():
    act = load_policy("pd").actor(FLAT)
    (short,) = Lockstep([BalanceEnv(FLAT, max_episode_steps=60)], act, [3]).play()
    assert (short.length, short.falls) == (60, 0)
    capped = Lockstep([BalanceEnv(FLAT)], act, [3], limit=25)  # a caller's cap
    assert [step.step for step in capped][-1] == 25
    assert capped.results[0].length == 25
    multi = bbbench.make_parallel("bbbench/MultiBalance-v1", max_episode_steps=30)
    played = MultiEpisode(multi, load_policy("pd").actor("bbbench/MultiBalance-v1"), 3).play()
    assert played.length == 30
    assert multi.agents == []

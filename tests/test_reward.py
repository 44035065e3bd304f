"""The shared reward in which staying up never costs (`StayUpReward`), and the task versions
that use it: each property the suite promises, on the reward itself and on real episodes."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import bbbench
from bbbench.evaluation import evaluate
from bbbench.policies import load_policy
from bbbench.tasks.reward import (
    RewardWeights,
    StayUpReward,
    TwistReward,
    ramp,
    step_outcome,
    tolerance,
)
from bbbench.tasks.suite import SUITE
from conftest import REWARD_SUCCESSORS

SUCCESSORS = REWARD_SUCCESSORS
SINGLE = [task for task in SUCCESSORS if not bbbench.spec(task).multi_agent]
MULTI = [task for task in SUCCESSORS if bbbench.spec(task).multi_agent]
BOARD = Path(__file__).parent.parent / "leaderboards"

REWARD = StayUpReward()
PITCHES = np.linspace(-1.0, 1.0, 81)  # rad: up to the fall limit
ERRORS = np.linspace(0.0, 5.0, 101)  # m/s: past anything the bot reaches


def test_every_latest_version_plays_the_new_reward_and_only_the_reward_changed():
    for new, old in SUCCESSORS.items():
        new_spec, old_spec = bbbench.spec(new), bbbench.spec(old)
        assert new_spec.reward == REWARD
        assert isinstance(old_spec.reward, RewardWeights)
        for field in ("terrain", "command", "sensors", "initial_pitch", "control_dt"):
            assert getattr(new_spec, field) == getattr(old_spec, field), (new, field)
        assert new_spec.eval_seeds == old_spec.eval_seeds
        assert new_spec.max_episode_steps == old_spec.max_episode_steps
        assert new_spec.group == old_spec.group
        assert new_spec.version_history[: len(old_spec.version_history)] == (
            old_spec.version_history
        )
        assert "staying up never costs" in new_spec.version_history[-1]
        assert new_spec.fingerprint != old_spec.fingerprint
        assert new_spec.random_return != old_spec.random_return


def test_the_latest_version_of_every_task_plays_the_new_reward():
    latest: dict[str, str] = {}
    for task_id in sorted(SUITE, key=lambda task_id: bbbench.spec(task_id).version):
        latest[bbbench.spec(task_id).name] = task_id
    # The successors of the published tasks, and the tasks first published on it.
    first_on_it = {"bbbench/PushRecovery-v0", "bbbench/MultiNoisySensors-v0"}
    first_on_it |= {t for t in SUITE if bbbench.spec(t).robot == "wheel-legged"}
    first_on_it |= {t for t in SUITE if bbbench.spec(t).coupling is not None}  # the teams
    first_on_it |= {t for t in latest.values() if bbbench.spec(t).robot == "two-wheel-steer"}
    assert sorted(latest.values()) == sorted({*SUCCESSORS, *first_on_it})
    # The shared form: StayUpReward, or its twin for a commanded yaw rate too.
    rewards = {type(bbbench.spec(task).reward) for task in latest.values()}
    assert rewards == {StayUpReward, TwistReward}


# -- a. each step earns between 0 and 0.1; 0.1 only upright and on target ----------------


def test_a_step_earns_between_0_and_the_maximum_and_the_maximum_only_upright_on_target():
    for pitch in PITCHES:
        for error in ERRORS:
            upright, velocity = REWARD.terms(float(pitch), float(error))
            assert upright >= 0.0
            assert velocity >= 0.0
            assert upright + velocity <= 0.1
            best = upright + velocity == 0.1
            inside = abs(pitch) <= REWARD.pitch_bound and error <= REWARD.velocity_bound
            # (outside by less than a rounding error, 1 - ratio**2 rounds to 1)
            near = abs(pitch) <= REWARD.pitch_bound + 1e-12 and error <= REWARD.velocity_bound
            assert best if inside else (not best or near)
    assert bbbench.spec("bbbench/Bumps-v2").max_return == 150.0


def test_tolerance_is_one_inside_the_bound_and_falls_to_zero_at_bound_plus_width():
    assert tolerance(0.05, 0.1, 0.5) == 1.0
    assert tolerance(-0.1, 0.1, 0.5) == 1.0
    assert tolerance(0.35, 0.1, 0.5) == 1.0 - 0.5**2
    assert tolerance(0.6, 0.1, 0.5) == 0.0
    assert tolerance(3.0, 0.1, 0.5) == 0.0
    values = [tolerance(x, 0.1, 0.5) for x in np.linspace(0.0, 1.0, 101)]
    assert all(a >= b for a, b in itertools.pairwise(values))  # never rises


def test_the_upright_term_rewards_standing_whatever_the_velocity_and_tracking_pays_more():
    standing_far_off_target = REWARD.terms(0.0, REWARD.velocity_bound + REWARD.tail_width)
    assert standing_far_off_target == (pytest.approx(0.01), 0.0)
    on_target = sum(REWARD.terms(0.0, 0.0))
    assert on_target > 9 * sum(standing_far_off_target)
    # Leaning further never earns more, nor does tracking worse.
    for error in (0.0, 0.2, 1.0):
        leans = [sum(REWARD.terms(float(p), error)) for p in np.linspace(0.0, 1.0, 51)]
        assert all(a >= b for a, b in itertools.pairwise(leans))
    for pitch in (0.0, 0.3):
        errors = [sum(REWARD.terms(pitch, float(e))) for e in ERRORS]
        assert all(a >= b for a, b in itertools.pairwise(errors))


def test_moving_towards_a_far_target_pays_before_the_bot_is_near_it():
    """The tail: 1.5 m/s short of the target, every 0.1 m/s closer earns more, so the way
    from standing to driving is uphill all along."""
    earned = [sum(REWARD.terms(0.0, error)) for error in np.arange(1.5, 0.3, -0.1)]
    assert all(later > earlier for earlier, later in itertools.pairwise(earned))
    assert ramp(1.1, 0.1, 2.0) == 0.5
    assert ramp(-0.05, 0.1, 2.0) == 1.0
    assert ramp(2.5, 0.1, 2.0) == 0.0


def test_the_old_reward_went_negative_while_the_bot_was_up():
    """The measured failure that made the new versions: 1 m/s off target and upright, the
    first reward paid nothing, and less than nothing further off."""
    old = RewardWeights()
    assert sum(old.terms(0.0, 1.0)) == 0.0
    assert sum(old.terms(0.0, 1.5)) < 0.0
    assert sum(REWARD.terms(0.0, 1.5)) > 0.0


@pytest.mark.parametrize("task_id", SINGLE)
def test_every_step_of_real_episodes_earns_0_to_0_1_as_the_sum_of_its_two_terms(task_id):
    env = gym.make(task_id)
    rng = np.random.default_rng(0)
    pd = load_policy("pd").actor(task_id)
    for seed, policy in ((5, "random"), (6, "pd")):
        observation, _ = env.reset(seed=seed)
        for _ in range(300):
            action = int(rng.integers(9)) if policy == "random" else pd(observation[None])[0]
            observation, reward, terminated, truncated, info = env.step(action)
            assert 0.0 <= reward <= 0.1
            assert reward == info["reward_upright"] + info["reward_velocity"]
            assert info["reward_upright"] >= 0.0
            assert info["reward_velocity"] >= 0.0
            if terminated or truncated:
                break


# -- b. staying up longer never lowers the return ----------------------------------------


@pytest.mark.parametrize("task_id", SINGLE)
def test_for_the_same_motion_staying_up_longer_never_lowers_the_return(task_id):
    """Replay one motion and stop it at every step: the return up to step k never falls
    as k grows, so a fall (which ends the episode at k) only forfeits what was to come."""
    env = gym.make(task_id)
    env.reset(seed=11)
    rewards = []
    for _ in range(400):
        _, reward, terminated, truncated, _ = env.step(6)  # a steady push forward: falls
        rewards.append(reward)
        if terminated or truncated:
            break
    assert terminated, "the motion was meant to end in a fall"
    returns = np.cumsum(rewards)
    assert np.all(np.diff(returns) >= 0.0)


@pytest.mark.parametrize("task_id", SINGLE)
def test_falling_at_once_never_scores_more_than_staying_up(task_id):
    zero, stand = (
        evaluate(load_policy(name), [task_id], episodes=4).document["tasks"][0]
        for name in ("zero", "stand")
    )
    assert all(episode["falls"] == 1 for episode in zero["episodes"])
    assert all(episode["success"] for episode in stand["episodes"])
    assert stand["aggregate"]["mean"] > zero["aggregate"]["mean"]


def test_on_the_old_terrain_reward_falling_at_once_scored_more_than_standing():
    """The failure the new versions fix, as published: on Bumps-v1 doing nothing (a fall
    within a second) out-scored standing up for the whole episode."""
    zero, stand = (
        evaluate(load_policy(name), ["bbbench/Bumps-v1"], episodes=4).document["tasks"][0]
        for name in ("zero", "stand")
    )
    assert stand["aggregate"]["mean"] < zero["aggregate"]["mean"] < 0.0


# -- c. the two named terms, in one place beneath both env APIs ---------------------------


@pytest.mark.parametrize("task_id", MULTI)
def test_every_bot_of_a_multi_bot_task_is_judged_by_the_single_bot_rules(task_id):
    env = bbbench.make_parallel(task_id)
    env.reset(seed=4)
    checked = 0
    for _ in range(60):
        if not env.agents:
            break
        _, rewards, terminations, _, infos = env.step(dict.fromkeys(env.agents, 6))
        steps = env.scene.steps
        for agent in env.agents:  # still in the world: its bot reads as it was judged
            index = env.agent_index[agent]
            state = env.scene.bots[index].read()
            target = float(env.scene.episode.targets[index, steps])
            reward, fell, info = step_outcome(state, target, env.task.reward)
            assert (rewards[agent], terminations[agent]) == (reward, fell)
            assert infos[agent] == {**info, "episode_seed": 4}  # every step says which episode
            assert 0.0 <= rewards[agent] <= 0.1
            checked += 1
    assert checked > 100


# -- d. standing earns credit, clearly less than doing the task --------------------------


def test_stand_is_pd_holding_target_velocity_zero_and_pd_itself_on_flat_ground():
    observation = np.array([0.05, -0.2, 3.0, 2.5, 1.5], dtype=np.float32)
    stand = load_policy("stand").actor("bbbench/VelocityTracking-v1")
    pd = load_policy("pd").actor("bbbench/VelocityTracking-v1")
    held = observation.copy()
    held[4] = 0.0
    assert stand(observation[None]) == pd(held[None])
    assert stand(observation[None]) != pd(observation[None])
    flat = "bbbench/FlatBalance-v1"
    one, other = (
        evaluate(load_policy(name), [flat], episodes=3).document["tasks"][0]["episodes"]
        for name in ("stand", "pd")
    )
    assert one == other


def _board_scores() -> dict[str, dict[str, float]]:
    """Each reference entry's normalized score per task, from the checked-in board (which
    `bbbench leaderboard check` re-scores from scratch in CI)."""
    board = json.loads((BOARD / "bbbench-v0.json").read_text())
    scores: dict[str, dict[str, float]] = {}
    for track in board["tracks"]:
        for method in track["methods"]:
            for task_id, task in method["tasks"].items():
                scores.setdefault(method["slug"], {})[task_id] = task["normalized_score"]
    return scores


@pytest.mark.parametrize("task_id", [task for task in SUCCESSORS if "FlatBalance" not in task])
def test_on_every_velocity_commanded_task_random_is_below_stand_below_pd(task_id):
    scores = _board_scores()
    random, stand, pd = (scores[slug][task_id] for slug in ("random", "stand", "pd"))
    assert random < stand < pd
    assert stand <= 0.4


def test_on_flat_ground_stand_scores_what_pd_scores():
    scores = _board_scores()
    assert scores["stand"]["bbbench/FlatBalance-v1"] == scores["pd"]["bbbench/FlatBalance-v1"]
    assert math.isclose(scores["pd"]["bbbench/FlatBalance-v1"], 1.0, abs_tol=0.01)

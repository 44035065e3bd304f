"""The task is neither trivial nor impossible: doing nothing falls, the PD baseline stands."""

from __future__ import annotations

import numpy as np

import bbbench
from bbbench.policies import PDController
from bbbench.policies.controllers.lqr import (
    COST_INPUT,
    COST_STATE,
    GAINS,
    MODEL_A,
    MODEL_B,
    LQRController,
    identify,
    lqr_gains,
)
from bbbench.robots import MODEL
from conftest import FLAT

SEEDS = range(20)


def episode(env, policy, seed: int) -> tuple[int, bool, float]:
    observation, _ = env.reset(seed=seed)
    total, steps = 0.0, 0
    while True:
        observation, reward, terminated, truncated, _ = env.step(policy(observation))
        total += reward
        steps += 1
        if terminated or truncated:
            return steps, terminated, total


def test_the_zero_action_falls_within_a_few_seconds_on_most_seeds():
    env = bbbench.make(FLAT)
    results = [episode(env, lambda observation: 4, seed) for seed in SEEDS]
    fell_fast = [terminated and steps <= 300 for steps, terminated, _ in results]  # 3 s
    assert sum(fell_fast) >= 0.9 * len(SEEDS)


def test_the_pd_baseline_stands_the_full_episode_on_most_seeds(action_mode):
    env = bbbench.make(FLAT, action_mode=action_mode)
    policy = PDController(action_mode=action_mode)
    results = [episode(env, policy, seed) for seed in SEEDS]
    full = [steps == 1500 and not terminated for steps, terminated, _ in results]
    assert sum(full) >= 0.9 * len(SEEDS)
    assert np.mean([total for *_, total in results]) > 0.9 * bbbench.spec(FLAT).max_return


def test_pd_predict_handles_a_batch_like_sb3():
    policy = PDController()
    env = bbbench.make(FLAT)
    observation, _ = env.reset(seed=0)
    actions, state = policy.predict(np.stack([observation, observation]))
    assert state is None
    assert actions.shape == (2,)
    assert actions[0] == policy(observation)


def test_the_pd_baseline_tracks_the_target_velocity_without_bias():
    env = bbbench.make("bbbench/VelocityTracking-v0")
    policy = PDController()
    errors = []
    for seed in range(5):
        observation, _ = env.reset(seed=seed)
        for _ in range(1500):
            observation, _, terminated, truncated, _ = env.step(policy(observation))
            state = env.unwrapped.scene.bots[0].read()
            errors.append(state.forward_velocity - observation[4])
            if terminated or truncated:
                break
    # Without the target fed forward it settled at twice the target: mean |error| 0.41 m/s.
    assert abs(np.mean(errors)) < 0.05
    assert np.mean(np.abs(errors)) < 0.25


# -- LQR -------------------------------------------------------------------------------


def test_the_lqr_baseline_stands_on_every_eval_seed_in_both_modes():
    from bbbench.evaluation import evaluate
    from bbbench.policies import load_policy

    for mode, episodes in (("discrete", None), ("continuous", 16)):
        policy = load_policy("lqr", action_mode=mode)
        document = evaluate(policy, [FLAT], episodes=episodes, workers=1).document
        aggregate = document["tasks"][0]["aggregate"]
        assert aggregate["success_rate"] == 1.0, mode
        assert aggregate["episodes"] == (episodes or 100)


def test_the_lqr_baseline_tracks_the_target_velocity_without_bias():
    env = bbbench.make("bbbench/VelocityTracking-v0")
    policy = LQRController()
    errors = []
    for seed in range(5):
        observation, _ = env.reset(seed=seed)
        for _ in range(1500):
            observation, _, terminated, truncated, _ = env.step(policy(observation))
            velocity = MODEL.wheel_radius * (observation[2] + observation[1])
            errors.append(velocity - observation[4])
            if terminated or truncated:
                break
    assert len(errors) == 5 * 1500  # no fall
    assert abs(np.mean(errors)) < 0.02
    assert np.mean(np.abs(errors)) < 0.25


def test_the_lqr_model_is_what_the_simulator_does():
    a, b = identify()
    assert np.allclose(a, MODEL_A, atol=2e-3)
    assert np.allclose(b, MODEL_B, atol=2e-3)
    designed = lqr_gains(MODEL_A, MODEL_B, COST_STATE, COST_INPUT)
    np.testing.assert_allclose(GAINS, designed, rtol=1e-12)
    closed_loop = MODEL_A - np.outer(MODEL_B, GAINS)
    assert np.max(np.abs(np.linalg.eigvals(closed_loop))) < 1.0  # stable

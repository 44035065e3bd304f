"""Perturbations: reset-time components, through one seam, hashed when not at default."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import bbbench
from bbbench.policies import PDController
from bbbench.tasks.perturbations import PERTURBATIONS, MotorStrength, PayloadMass
from bbbench.tasks.spec import SeedStreams, seed_streams

VELOCITY = "bbbench/VelocityTracking-v1"
SEED = 2**31 + 3


def pd_episode(env, seed: int = SEED, steps: int = 1500) -> np.ndarray:
    observation, _ = env.reset(seed=seed)
    pd, seen = PDController(), [observation]
    for _ in range(steps):
        observation, _, terminated, truncated, _ = env.step(pd(observation))
        seen.append(observation)
        if terminated or truncated:
            break
    return np.array(seen)


def test_the_earlier_streams_draw_as_before_the_perturbation_stream():
    earlier = [f for f in SeedStreams._fields if f != "perturbation"]
    children = np.random.SeedSequence(SEED).spawn(len(earlier))
    streams = seed_streams(SEED)
    for name, child in zip(earlier, children, strict=True):
        expected = np.random.default_rng(child).random(4)
        assert np.array_equal(getattr(streams, name).random(4), expected), name


@pytest.mark.parametrize("keyword", list(PERTURBATIONS))
def test_a_keyword_at_its_default_makes_the_same_task(keyword):
    default = PERTURBATIONS[keyword]()
    value = next(iter(default.__dict__.values()))
    plain, given = gym.make(VELOCITY), gym.make(VELOCITY, **{keyword: value})
    assert given.unwrapped.task == plain.unwrapped.task
    assert given.unwrapped.task.fingerprint == plain.unwrapped.task.fingerprint
    assert np.array_equal(pd_episode(given), pd_episode(plain))


@pytest.mark.parametrize(("keyword", "value"), [("payload_mass", 0.5), ("motor_strength", 0.3)])
def test_a_perturbed_task_has_its_own_fingerprint_and_plays_its_own_episodes(keyword, value):
    plain, perturbed = gym.make(VELOCITY), gym.make(VELOCITY, **{keyword: value})
    assert perturbed.unwrapped.task.fingerprint != plain.unwrapped.task.fingerprint
    assert perturbed.spec.kwargs[keyword] == value
    episode = pd_episode(perturbed)
    assert not np.array_equal(episode, pd_episode(plain))
    assert np.array_equal(pd_episode(perturbed), episode)  # reproducible, reset after reset


def test_payload_mass_and_motor_strength_reach_the_robot():
    env = gym.make(VELOCITY, payload_mass=0.75, motor_strength=0.5)
    env.reset(seed=SEED)
    bot = env.unwrapped.scene.bots[0]
    mass = bot._client.getDynamicsInfo(bot.body, -1)[0]
    assert mass == pytest.approx(0.8 + 0.75)  # the URDF's 0.8 kg torso, and the payload
    assert bot._motor_forces == (0.5 * bot.model.motor_torque_limit,) * 2


def test_every_bot_of_a_multi_bot_task_carries_the_payload():
    env = bbbench.make_parallel("bbbench/MultiBalance-v1", payload_mass=0.4)
    env.reset(seed=SEED)
    masses = {bot._client.getDynamicsInfo(bot.body, -1)[0] for bot in env.scene.bots}
    assert len(masses) == 1
    assert env.task.perturbations == (PayloadMass(0.4),)
    env.close()


def test_perturbations_keep_the_order_of_their_keywords():
    task = bbbench.spec(VELOCITY)
    one = task.with_perturbation(PayloadMass(0.2)).with_perturbation(MotorStrength(0.8))
    other = task.with_perturbation(MotorStrength(0.8)).with_perturbation(PayloadMass(0.2))
    assert one == other
    assert one.with_perturbation(PayloadMass(0.0)).perturbations == (MotorStrength(0.8),)


@pytest.mark.parametrize(
    ("keyword", "value", "expected"),
    [
        ("payload_mass", -0.1, "payload_mass must be in [0, 10]"),
        ("payload_mass", "heavy", "payload_mass must be a number"),
        ("motor_strength", 0.0, "motor_strength must be in [0.05, 10]"),
        ("motor_strength", float("nan"), "motor_strength must be a number"),
    ],
)
def test_a_bad_value_says_what_is_expected(keyword, value, expected):
    with pytest.raises(ValueError, match=expected.replace("[", r"\[").replace("]", r"\]")):
        gym.make(VELOCITY, **{keyword: value})


def test_an_unknown_keyword_lists_the_perturbations():
    with pytest.raises(TypeError, match="payload_mass, motor_strength"):
        gym.make(VELOCITY, payload=1.0)

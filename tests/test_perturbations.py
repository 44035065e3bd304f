"""Perturbations: reset-time components, through one seam, hashed when not at default."""

from __future__ import annotations

import itertools
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import bbbench
from bbbench.policies import PDController
from bbbench.tasks.perturbations import (
    PERTURBATIONS,
    PUSH_INTERVAL,
    MotorStrength,
    PayloadMass,
    axes_markdown,
)
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
    mass = bot.client.getDynamicsInfo(bot.body, -1)[0]
    assert mass == pytest.approx(0.8 + 0.75)  # the URDF's 0.8 kg torso, and the payload
    assert bot.motor_forces == (0.5 * bot.model.motor_torque_limit,) * 2


def test_every_bot_of_a_multi_bot_task_carries_the_payload():
    env = bbbench.make_parallel("bbbench/MultiBalance-v1", payload_mass=0.4)
    env.reset(seed=SEED)
    masses = {bot.client.getDynamicsInfo(bot.body, -1)[0] for bot in env.scene.bots}
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
        ("motor_strength", 0.0, "motor_strength must be in (0, 10]"),
        ("motor_strength", float("nan"), "motor_strength must be a number"),
        ("friction", 0.0, "friction must be in (0, 10]"),
        ("friction", -1.0, "friction must be in (0, 10]"),
        ("action_delay", 1.5, "action_delay must be a whole number"),
        ("action_delay", -1, "action_delay must be in [0, 100]"),
        ("action_delay", True, "action_delay must be a whole number"),
        ("com_offset", 0.5, "com_offset must be in [-0.2, 0.2]"),
        ("sensor_noise", -0.1, "sensor_noise must be in [0, 10]"),
        ("push", float("inf"), "push must be a number"),
    ],
)
def test_a_bad_value_says_what_is_expected(keyword, value, expected):
    with pytest.raises(ValueError, match=re.escape(expected)):
        gym.make(VELOCITY, **{keyword: value})


def test_an_unknown_keyword_lists_the_perturbations():
    with pytest.raises(TypeError, match=", ".join(PERTURBATIONS)):
        gym.make(VELOCITY, payload=1.0)


def test_sensor_noise_scales_a_noisy_task_and_adds_the_tutorials_noise_to_a_perfect_one():
    noisy = "bbbench/NoisySensors-v1"
    assert gym.make(noisy, sensor_noise=1.0).unwrapped.task == bbbench.spec(noisy)
    silenced = gym.make(noisy, sensor_noise=0.0).unwrapped
    assert silenced.task.perturbations
    assert silenced.task != bbbench.spec(noisy)
    tripled = gym.make(noisy, sensor_noise=3.0).unwrapped
    silenced.reset(seed=SEED)
    tripled.reset(seed=SEED)
    base = gym.make(noisy).unwrapped
    base.reset(seed=SEED)
    assert np.array_equal(tripled.scene.episode.sensor_errors, 3 * base.scene.episode.sensor_errors)
    assert not silenced.scene.episode.sensor_errors.any()
    # A perfect task observes through the tutorial's noise, drawn from the perturbation
    # stream: the true state is the same at reset, the observation is not.
    plain, noised = gym.make(VELOCITY).unwrapped, gym.make(VELOCITY, sensor_noise=1.0).unwrapped
    first, second = plain.reset(seed=SEED)[0], noised.reset(seed=SEED)[0]
    assert plain.scene.bots[0].read() == noised.scene.bots[0].read()
    assert not np.array_equal(first[:3], second[:3])
    assert np.array_equal(first[3:], second[3:])


def test_sensor_noise_does_not_apply_to_a_multi_bot_task():
    with pytest.raises(ValueError, match="sensor_noise does not apply to bbbench/MultiBalance"):
        bbbench.make_parallel("bbbench/MultiBalance-v1", sensor_noise=1.0)


def test_friction_scales_every_ground_body():
    env = gym.make("bbbench/Bumps-v2", friction=0.4).unwrapped
    env.reset(seed=SEED)
    ground, client = env.scene.ground, env.scene.world.client
    bodies = [ground.body, *ground.surround]
    assert [client.getDynamicsInfo(body, -1)[1] for body in bodies] == [0.4] * len(bodies)


def test_com_offset_moves_the_centre_of_mass_not_the_torso_or_its_readings():
    plain, shifted = gym.make(VELOCITY).unwrapped, gym.make(VELOCITY, com_offset=0.03).unwrapped
    first, second = plain.reset(seed=SEED)[0], shifted.reset(seed=SEED)[0]
    assert np.array_equal(first, second)  # the same lean, read from the same torso
    bot = shifted.scene.bots[0]
    plain_state, state = plain.scene.bots[0].read(), bot.read()
    assert np.allclose(state.axle, plain_state.axle, atol=1e-12)
    assert np.allclose(state.position, plain_state.position, atol=1e-12)
    centre = bot.client.getBasePositionAndOrientation(bot.body)[0]
    heading = np.array([*state.heading, 0.0])
    # The centre of mass is 3 cm further along the torso's forward axis (leaning, so
    # not quite horizontal: compare along the heading).
    moved = np.subtract(centre, state.position)
    assert np.dot(moved, heading) == pytest.approx(0.03 * np.cos(state.pitch), abs=1e-9)
    assert bot.body == plain.scene.bots[0].body  # reloaded into the id it freed


def test_pushes_come_every_two_to_four_seconds_and_start_at_their_step():
    plain, pushed = gym.make(VELOCITY).unwrapped, gym.make(VELOCITY, push=0.5).unwrapped
    plain.reset(seed=SEED)
    pushed.reset(seed=SEED)
    steps = sorted({step for step, _, _ in pushed.scene.episode.pushes})
    low, high = (round(t / pushed.task.control_dt) for t in PUSH_INTERVAL)
    assert low <= steps[0] <= high
    assert all(low - 1 <= b - a <= high + 1 for a, b in itertools.pairwise(steps))
    assert len(steps) >= pushed.task.max_episode_steps // high - 1
    actions = [4] * (steps[0] + 1)  # no change of command: only the push tells them apart
    before = [plain.step(a)[0] for a in actions]
    after = [pushed.step(a)[0] for a in actions]
    assert all(np.array_equal(x, y) for x, y in zip(before[:-1], after[:-1], strict=True))
    assert not np.array_equal(before[-1], after[-1])  # the push acts in its own step


def test_pushes_reach_every_bot_of_a_multi_bot_task_at_their_own_times():
    env = bbbench.make_parallel("bbbench/MultiBalance-v1", push=0.5)
    env.reset(seed=SEED)
    pushed = {bot for _, bot, _ in env.scene.episode.pushes}
    assert pushed == set(range(env.scene.n_bots))
    env.close()


@pytest.mark.parametrize("delay", [1, 3])
def test_action_delay_shifts_the_wheel_command_response_by_exactly_k_steps(delay):
    """With a delay of k, actions A play the physics of k no-change actions then A: the
    true state is the same at every step, and the command asked for leads by k steps."""
    actions = [int(a) for a in np.random.default_rng(1).integers(0, 9, size=60)]
    delayed = gym.make(VELOCITY, action_delay=delay).unwrapped
    undelayed = gym.make(VELOCITY).unwrapped
    seen = [delayed.reset(seed=SEED)[0]] + [delayed.step(a)[0] for a in actions]
    plain = [undelayed.reset(seed=SEED)[0]]
    plain += [undelayed.step(a)[0] for a in [4] * delay + actions]
    seen, plain = np.array(seen), np.array(plain)
    assert np.array_equal(seen[:, :3], plain[: len(seen), :3])  # pitch, rate, wheel speed
    assert np.array_equal(seen[:, 3], plain[delay:, 3])  # the command, k steps ahead
    assert not np.array_equal(seen[:, 3], plain[: len(seen), 3])


# Per axis: two values, each further from the default, that cost PD some of its return
# (measured on VelocityTracking-v1: a payload up to 4 kg and a delay up to 10 steps do
# not cost PD anything; its heavier torso falls more slowly).
DIRECTIONS = {
    "payload_mass": (8.0, 10.0),
    "com_offset": (0.01, 0.025),
    "friction": (0.2, 0.1),
    "motor_strength": (0.1, 0.05),
    "action_delay": (15, 20),
    "sensor_noise": (1.0, 3.0),
    "push": (0.5, 1.0),
}
_SCORES = """
import gymnasium as gym, numpy as np, bbbench
from bbbench.policies import PDController
def pd_returns(keyword, value, seeds):
    env = gym.make("{task}", **({{keyword: value}} if keyword else {{}}))
    returns = []
    for seed in seeds:
        observation, _ = env.reset(seed=seed)
        pd, total = PDController(), 0.0
        while True:
            observation, reward, terminated, truncated, _ = env.step(pd(observation))
            total += reward
            if terminated or truncated:
                break
        returns.append(total)
    return returns
"""


def _direction_scores() -> dict:
    seeds = bbbench.spec(VELOCITY).eval_seeds[:3]
    namespace: dict = {}
    exec(_SCORES.format(task=VELOCITY), namespace)  # the same code as in the other process
    scores = {("", 0): namespace["pd_returns"](None, 0, seeds)}
    for keyword, values in DIRECTIONS.items():
        for value in values:
            scores[keyword, value] = namespace["pd_returns"](keyword, value, seeds)
    scores["com_offset", -0.025] = namespace["pd_returns"]("com_offset", -0.025, seeds)
    return scores


def test_each_axis_moves_pds_score_the_expected_way_the_same_in_another_process():
    scores = _direction_scores()
    base = np.mean(scores["", 0])
    for keyword, (milder, stronger) in DIRECTIONS.items():
        mild, strong = np.mean(scores[keyword, milder]), np.mean(scores[keyword, stronger])
        assert base > mild > strong, (keyword, base, mild, strong)
    assert np.mean(scores["com_offset", -0.025]) < base  # backward costs too
    script = _SCORES.format(task=VELOCITY) + textwrap.dedent(
        f"""
        seeds = bbbench.spec("{VELOCITY}").eval_seeds[:3]
        for keyword, values in {DIRECTIONS!r}.items():
            for value in values:
                print("returns", keyword, value, pd_returns(keyword, value, seeds).__repr__())
        """
    )
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    ).stdout
    lines = [line.split(" ", 3) for line in out.splitlines() if line.startswith("returns ")]
    assert len(lines) == sum(len(values) for values in DIRECTIONS.values())
    for _, keyword, value, returns in lines:
        value = type(DIRECTIONS[keyword][0])(value)
        assert eval(returns) == scores[keyword, value], (keyword, value)  # the same bits


def test_the_table_of_axes_in_the_guide_is_the_modules():
    table = axes_markdown()
    guide = (Path(__file__).parents[1] / "docs" / "guides" / "robustness.md").read_text()
    assert table in guide
    for kind in PERTURBATIONS.values():
        for value in kind.grid:
            kind(value)  # every grid value is accepted


def test_push_recovery_shoves_harder_each_time_and_its_keyword_keeps_the_growth():
    task = bbbench.spec("bbbench/PushRecovery-v0")
    (push,) = task.perturbations
    assert push.growth > 0
    env = gym.make(task.id).unwrapped
    env.reset(seed=SEED)
    sizes = [abs(impulse) for _, _, impulse in env.scene.episode.pushes]
    assert len(sizes) >= 4
    assert sizes == sorted(sizes)
    assert sizes[0] >= push.impulse
    assert sizes[-1] > push.impulse + push.growth * 10  # the last, after more than 10 s
    softer = gym.make(task.id, push=0.2).unwrapped.task
    assert softer.perturbations == (type(push)(0.2, push.growth),)
    assert softer.fingerprint != task.fingerprint
    assert gym.make(task.id, push=push.impulse).unwrapped.task == task  # as built

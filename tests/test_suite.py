"""The suite: every task shares the interface, is deterministic, and does what it says."""

from __future__ import annotations

import dataclasses
import hashlib
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gymnasium_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import bbbench
from bbbench.policies import PDController
from bbbench.tasks.sensors import NoisySensors
from bbbench.tasks.spec import TRAINING_SEEDS
from bbbench.terrain import Bumps, HeightfieldTerrain
from conftest import FLAT, fixed_actions, rollout

SINGLE_BOT = bbbench.list_tasks(multi_agent=False)
# The two-wheel bot's single-bot tasks: one interface (the wheel-legged robot's tasks share
# theirs, tests/test_wheel_legged.py).
TASKS = [t for t in SINGLE_BOT if bbbench.spec(t).robot == "two-wheel"]
# Every single-bot task in every action mode its robot takes.
TASK_MODES = [
    pytest.param(t, mode, id=f"{t}-{mode}")
    for t in SINGLE_BOT
    for mode in bbbench.spec(t).robot_model.action_modes
]


def test_the_suite_has_its_five_single_bot_tasks():
    names = {"FlatBalance", "VelocityTracking", "NoisySensors", "Bumps", "Obstacles"}
    assert {task_id.split("/")[1].split("-")[0] for task_id in TASKS} >= names


@pytest.mark.parametrize(("task_id", "action_mode"), TASK_MODES)
def test_every_task_passes_both_checkers(task_id, action_mode):
    gymnasium_check_env(
        gym.make(task_id, action_mode=action_mode).unwrapped, skip_render_check=True
    )
    env = gym.make(task_id, action_mode=action_mode).unwrapped  # (-v0 of Bumps: "out of date")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_check_env(env, warn=True)
    assert [str(w.message) for w in caught] == []


def test_every_task_has_the_same_spaces(action_mode):
    envs = [gym.make(task_id, action_mode=action_mode) for task_id in TASKS]
    assert all(env.observation_space == envs[0].observation_space for env in envs)
    assert all(env.action_space == envs[0].action_space for env in envs)


@pytest.mark.parametrize(("task_id", "action_mode"), TASK_MODES)
def test_20000_random_steps_stay_finite_and_in_space(task_id, action_mode):
    env = gym.make(task_id, action_mode=action_mode)
    env.action_space.seed(0)
    observation, _ = env.reset(seed=0)
    for _ in range(20_000):
        assert np.all(np.isfinite(observation))
        assert env.observation_space.contains(observation), observation
        observation, reward, terminated, truncated, _ = env.step(env.action_space.sample())
        assert np.isfinite(reward)
        if terminated or truncated:
            observation, _ = env.reset()


def digests(task_ids) -> list[str]:
    out = []
    for task_id in task_ids:
        observations, rewards = rollout(bbbench.make(task_id), 2**31 + 3, fixed_actions(400))
        out.append(hashlib.sha256(observations.tobytes() + rewards.tobytes()).hexdigest())
    return out


def test_every_task_is_deterministic_across_processes():
    script = textwrap.dedent(
        f"""
        from test_suite import digests
        for digest in digests({TASKS!r}):
            print("digest", digest)
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", script],
        cwd=Path(__file__).parent,
        capture_output=True,
        text=True,
        check=True,
    )
    there = [line.split()[1] for line in done.stdout.splitlines() if line.startswith("digest ")]
    assert there == digests(TASKS)


def test_reset_without_a_seed_plays_training_seeds_never_eval_seeds():
    env = bbbench.make("bbbench/Bumps-v0")
    env.reset(seed=123)
    drawn = [env.reset()[1]["episode_seed"] for _ in range(200)]
    assert all(seed in TRAINING_SEEDS for seed in drawn)
    for task_id in TASKS:
        eval_seeds = bbbench.spec(task_id).eval_seeds
        assert len(eval_seeds) >= 100
        assert not set(eval_seeds) & set(drawn)
        assert all(seed not in TRAINING_SEEDS for seed in eval_seeds)


def test_validation_seeds_are_public_and_apart_from_training_and_evaluation_seeds():
    for task_id in bbbench.list_tasks():
        spec = bbbench.spec(task_id)
        assert len(spec.validation_seeds) == 100
        assert spec.seeds("validation") == spec.validation_seeds
        assert spec.seeds() == spec.eval_seeds
        assert not set(spec.validation_seeds) & set(spec.eval_seeds)
        assert all(seed not in TRAINING_SEEDS for seed in spec.validation_seeds)
    with pytest.raises(ValueError, match="must lie outside the training and evaluation seeds"):
        dataclasses.replace(bbbench.spec(TASKS[0]), validation_seeds=(5,))
    with pytest.raises(ValueError, match="the seeds are 'evaluation' or 'validation', got 'test'"):
        bbbench.spec(TASKS[0]).seeds("test")


def test_an_episode_seed_decides_the_episode_whoever_asks():
    env = bbbench.make("bbbench/Bumps-v0")
    env.reset(seed=5)
    seed = env.reset()[1]["episode_seed"]
    drawn = env.unwrapped.scene.ground.heightmap.heights.copy()
    env.reset(seed=seed)  # the same training seed, asked for by name
    assert np.array_equal(env.unwrapped.scene.ground.heightmap.heights, drawn)


def test_difficulty_changes_the_terrain_and_is_recorded():
    easy = gym.make("bbbench/Bumps-v0", difficulty=0.0)
    hard = gym.make("bbbench/Bumps-v0", difficulty=1.0)
    assert easy.spec.kwargs["difficulty"] == 0.0
    assert (
        gym.make("bbbench/Bumps-v0").spec.kwargs["difficulty"]
        == bbbench.spec("bbbench/Bumps-v0").difficulty
    )
    easy.reset(seed=2**31)
    hard.reset(seed=2**31)
    low = easy.unwrapped.scene.ground.heightmap.heights.max()
    high = hard.unwrapped.scene.ground.heightmap.heights.max()
    assert high > low
    assert easy.unwrapped.task.fingerprint != hard.unwrapped.task.fingerprint


@pytest.mark.parametrize("bad", [-0.5, 2.0])
def test_difficulty_outside_0_1_is_refused(bad):
    with pytest.raises(ValueError, match=r"difficulty must be a number in \[0, 1\]"):
        gym.make("bbbench/Obstacles-v0", difficulty=bad)


def test_a_flat_task_refuses_a_difficulty_naming_what_it_accepts():
    with pytest.raises(TypeError, match=r"\['difficulty'\].*action_mode.*render_mode"):
        gym.make(FLAT, difficulty=0.5)


def test_velocity_targets_change_within_an_episode_and_the_reward_tracks_them():
    env = bbbench.make("bbbench/VelocityTracking-v0")
    observation, _ = env.reset(seed=2**31 + 1)
    policy = PDController()
    targets, rewards, velocities = [], [], []
    for _ in range(1500):
        observation, reward, terminated, truncated, _ = env.step(policy(observation))
        targets.append(float(observation[4]))
        rewards.append(reward)
        velocities.append(env.unwrapped.scene.bots[0].read().forward_velocity)
        if terminated or truncated:
            break
    assert len(set(targets)) >= 3  # piecewise constant, changing every 2-5 s
    assert max(targets) - min(targets) > 0.3
    errors = np.abs(np.array(velocities) - np.array(targets))
    # The reward falls as the tracking error grows (0.1 per m/s, upright term aside).
    assert np.corrcoef(errors, rewards)[0, 1] < -0.9


def test_noisy_sensors_have_the_stated_statistics():
    env = bbbench.make("bbbench/NoisySensors-v0")
    sensors = env.unwrapped.task.sensors
    policy = PDController()
    biases, residual_std = [], []
    for seed in range(40):
        observation, _ = env.reset(seed=seed)
        errors = []
        for _ in range(200):
            true_pitch = env.unwrapped.scene.bots[0].read().pitch
            errors.append(float(observation[0]) - true_pitch)
            observation, _, terminated, truncated, _ = env.step(policy(observation))
            if terminated or truncated:
                break
        biases.append(np.mean(errors))
        residual_std.append(np.std(errors))
    # Per-episode bias N(0, 0.1) rad, per-step noise of 0.05 rad.
    assert np.std(biases) == pytest.approx(sensors.bias_std[0], rel=0.35)
    assert np.mean(residual_std) == pytest.approx(sensors.noise_std[0], rel=0.1)


def test_the_pd_baseline_survives_most_bumps_eval_seeds_at_low_difficulty():
    env = bbbench.make("bbbench/Bumps-v0", difficulty=0.1)
    policy = PDController()
    survived = 0
    seeds = bbbench.spec("bbbench/Bumps-v0").eval_seeds[:10]
    for seed in seeds:
        observation, _ = env.reset(seed=seed)
        terminated = truncated = False
        while not (terminated or truncated):
            observation, _, terminated, truncated, _ = env.step(policy(observation))
        survived += not terminated
        # ...and makes progress across the terrain.
        if not terminated:
            assert env.unwrapped.scene.bots[0].read().position[1] > 2.0
    assert survived >= 0.8 * len(seeds)


@pytest.mark.parametrize(
    ("make", "names"),
    [
        (lambda: Bumps(heigth=0.1), "min_height, extra_height, feature_size"),
        (lambda: HeightfieldTerrain(cellsize=0.1), "generator, difficulty, size, cell_size"),
        (lambda: NoisySensors(bias=0.1), "bias_std, noise_std, delay_steps"),
    ],
    ids=["generator", "terrain", "sensors"],
)
def test_an_unknown_terrain_or_noise_parameter_names_the_accepted_ones(make, names):
    with pytest.raises(TypeError, match="accepted: " + names):
        make()


def test_noise_needs_one_deviation_per_reading():
    with pytest.raises(ValueError, match="one standard deviation per reading"):
        NoisySensors(noise_std=(0.1, 0.2))


def test_a_taskspec_where_an_id_is_taken_says_how_to_make_its_env():
    made = dataclasses.replace(bbbench.spec("bbbench/BeamCarry-v0"), id="bbbench/Made-v0")
    with pytest.raises(ValueError, match=r"give a task ID, not a TaskSpec \('bbbench/Made-v0'\)"):
        bbbench.make_parallel(made)

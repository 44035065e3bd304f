"""The episode written once: `Scene` under both env APIs, and the play loops."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import bbbench
from bbbench.cli import main
from bbbench.evaluation.play import Lockstep, MultiEpisode
from bbbench.policies import PDController
from bbbench.tasks.sensors import NoisySensors

FLAT, NOISY, BUMPS = "bbbench/FlatBalance-v0", "bbbench/NoisySensors-v0", "bbbench/Bumps-v1"
MULTI = "bbbench/MultiBumps-v0"


def test_both_envs_info_carries_the_reward_terms():
    env = bbbench.make(NOISY).unwrapped
    env.reset(seed=3)
    for _ in range(30):
        _, reward, _, _, info = env.step(5)
        state = env.scene.bots[0].read()
        assert (info["reward_upright"], info["reward_velocity"]) == env.task.reward.terms(
            state.pitch, info["velocity_error"]
        )
        assert reward == info["reward_upright"] + info["reward_velocity"]
    parallel = bbbench.make_parallel(MULTI)
    parallel.reset(seed=3)
    _, rewards, _, _, infos = parallel.step(dict.fromkeys(parallel.agents, 4))
    for agent, reward in rewards.items():
        assert reward == infos[agent]["reward_upright"] + infos[agent]["reward_velocity"]


def test_the_episode_is_what_the_seed_drew_and_is_read_only():
    env = bbbench.make(NOISY).unwrapped
    assert env.scene.episode is None  # nothing drawn before the first reset
    observation, info = env.reset(seed=11)
    episode = env.scene.episode
    assert episode.seed == info["episode_seed"] == 11
    assert episode.targets.shape == (1, env.task.max_episode_steps + 1)
    assert episode.sensor_errors.shape == (env.task.max_episode_steps + 1, 3)
    assert episode.heightmap is None  # flat ground
    # The observation's target is the drawn one, its pitch the true one plus the error.
    assert observation[4] == np.float32(episode.targets[0, 0])
    true_pitch = env.scene.bots[0].read().pitch
    assert observation[0] == np.float32(true_pitch + episode.sensor_errors[0, 0])
    with pytest.raises(ValueError, match="read-only"):
        episode.targets[0, 0] = 0.0
    env.reset(seed=12)
    assert env.scene.episode is not episode
    assert episode.seed == 11


def test_a_multi_bot_scene_draws_per_bot():
    env = bbbench.make_parallel(MULTI, n_bots=5)
    env.reset(seed=2)
    episode = env.scene.episode
    assert episode.targets.shape == (5, env.task.max_episode_steps + 1)
    assert len(episode.poses) == len(episode.pitches) == 5
    assert episode.heightmap is not None
    assert episode.sensor_errors is None
    assert env.scene.live == [0, 1, 2, 3, 4]
    for bot, ((x, y), _) in zip(env.scene.bots, episode.poses, strict=True):
        assert np.allclose(bot.read().axle[:2], (x, y), atol=0.05)


def test_keyword_errors_name_what_each_env_accepts():
    with pytest.raises(TypeError, match=r"\['n_bots'\] for bbbench/FlatBalance-v0: accepted"):
        bbbench.make(FLAT, n_bots=3)
    with pytest.raises(TypeError, match=r"\['height_scan'\] for bbbench/MultiBumps-v0"):
        bbbench.make_parallel(MULTI, height_scan=True)
    with pytest.raises(ValueError, match="render_mode must be None or one of"):
        bbbench.make_parallel(MULTI, render_mode="human")


def test_lockstep_yields_the_reset_then_each_step_and_ends_every_lane():
    envs = [bbbench.make(BUMPS).unwrapped for _ in range(3)]
    seeds = bbbench.spec(BUMPS).eval_seeds[:3]
    policy = PDController()
    lockstep = Lockstep(envs, lambda batch, rngs: [policy(row) for row in batch], seeds, 300)
    played = list(lockstep)
    assert played[0].step == 0
    assert played[0].rewards is None
    assert played[0].lanes == [0, 1, 2]
    assert [step.step for step in played] == list(range(len(played)))
    ended = [lane for step in played for lane in step.ended]
    assert sorted(ended) == [0, 1, 2]  # each lane ends once
    for result, lane in zip(lockstep.results, range(3), strict=True):
        last = next(step.step for step in played if lane in step.ended)
        assert result.length == last
        returns = sum(s.rewards[s.lanes.index(lane)] for s in played[1:] if lane in s.lanes)
        assert result.episode_return == pytest.approx(returns)
    # The same seeds played again, one lane at a time, give the same results.
    alone = [Lockstep([envs[0]], lockstep.act, [seed], 300).play()[0] for seed in seeds]
    assert alone == lockstep.results


def test_multi_episode_yields_by_agent_and_scores_as_evaluation():
    env = bbbench.make_parallel(MULTI, max_episode_steps=60)
    policy = PDController()
    episode = MultiEpisode(env, lambda batch, rngs: [policy(row[:5]) for row in batch], 4)
    played = list(episode)
    assert played[0].rewards is None
    assert set(played[0].observations) == set(env.possible_agents)
    assert played[-1].step == episode.result.length == 60
    total = sum(sum(step.rewards.values()) for step in played[1:])
    assert episode.result.episode_return == pytest.approx(total / len(env.possible_agents))


def test_dev_golden_reports_every_task_ok(capsys):
    assert main(["dev", "golden"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == len(bbbench.list_tasks())
    assert all(line.endswith("  ok") for line in lines), lines


MULTI_NOISY = "bbbench/MultiNoisySensors-v0"


def test_each_bot_of_a_noisy_group_reads_through_its_own_sensors():
    """MultiNoisySensors-v0: each bot's three readings are its true state plus its own
    errors at that step, drawn per bot; the rest of its row is MultiBalance-v1's."""
    noisy = bbbench.make_parallel(MULTI_NOISY)
    exact = bbbench.make_parallel("bbbench/MultiBalance-v1")
    observations, _ = noisy.reset(seed=5)
    truths, _ = exact.reset(seed=5)
    errors = noisy.scene.episode.sensor_errors
    assert errors.shape == (4, noisy.task.max_episode_steps + 1, 3)
    biases = {round(float(errors[i, :, 0].mean()), 2) for i in range(4)}
    assert len(biases) > 1  # each bot its own bias, not one for the group
    actions = dict.fromkeys(noisy.agents, 6)
    for step in range(40):
        if step:
            observations, *_ = noisy.step(actions)
            truths, *_ = exact.step(actions)
        for i, agent in enumerate(noisy.agents):
            state = noisy.scene.bots[i].read()
            read = np.add((state.pitch, state.pitch_rate, state.wheel_speed), errors[i, step])
            assert np.array_equal(observations[agent][:3], np.float32(read))
            # The same world as MultiBalance-v1's: the rest of the row is its, bit for bit.
            assert np.array_equal(observations[agent][3:], truths[agent][3:])


def test_the_first_bots_errors_are_one_store_for_reading_and_live_readings():
    """`scene.sensor_errors` (what a perturbation replaces) is the first bot's errors as
    both `reading` and `live_readings` read them: one store, never a stale copy."""
    scene = bbbench.make_parallel(MULTI_NOISY).scene
    scene.reset(seed=3)
    states = [bot.read() for bot in scene.bots]
    scene.sensor_errors = [(1.0, 2.0, 3.0)] * len(scene.sensor_errors)
    state = states[0]
    shifted = (state.pitch + 1.0, state.pitch_rate + 2.0, state.wheel_speed + 3.0)
    assert scene.reading(state, 7) == shifted
    first, second = scene.live_readings(states, 7)[:2]
    assert first == shifted
    assert second != (
        states[1].pitch + 1.0,
        states[1].pitch_rate + 2.0,
        states[1].wheel_speed + 3.0,
    )


def test_a_scenario_that_reads_the_true_state_refuses_noisy_or_delayed_sensors():
    with pytest.raises(ValueError, match="'swap' scenario observes through perfect sensors only"):
        dataclasses.replace(bbbench.spec("bbbench/Swap-v0"), sensors=NoisySensors())
    delayed = "a group's sensors are not delayed: give delay_steps=0, got 1"
    with pytest.raises(ValueError, match=delayed):
        dataclasses.replace(bbbench.spec(MULTI_NOISY), sensors=NoisySensors(delay_steps=1))

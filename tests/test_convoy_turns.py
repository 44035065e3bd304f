"""ConvoyTurns (`bbbench.tasks.scenarios.convoy.ConvoyTurns`): Convoy's tethered column
of steering bots, its front bot commanded a velocity and a yaw rate; `team` steers the
followers after the bot ahead."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pettingzoo.test import parallel_seed_test

import bbbench
from bbbench.policies import load_policy
from bbbench.policies.controllers.steer import SteerController
from bbbench.policies.controllers.team import SteeringTeam

TASK = "bbbench/ConvoyTurns-v0"


def test_only_the_front_bot_observes_the_command():
    env = bbbench.make_parallel(TASK)
    observations, _ = env.reset(seed=2)
    velocity, yaw_rate = env.unwrapped.scene.episode.targets[0][0]
    layout = [field.name for field in env.unwrapped.scene.scenario.layout]
    assert layout[8] == "target_yaw_rate"
    assert env.observation_space("bot_0").shape == (len(layout),)
    front, *followers = observations.values()
    assert front[4] == np.float32(velocity)
    assert front[8] == np.float32(yaw_rate)
    for observation in followers:
        assert observation[4] == 0.0
        assert observation[8] == 0.0
    env.close()


def test_the_team_reward_scores_the_front_bots_turn_and_the_teams_speed():
    env = bbbench.make_parallel(TASK)
    observations, infos = env.reset(seed=2)
    law = SteerController("discrete", guide=SteeringTeam(env.unwrapped.scene.scenario))
    for _ in range(200):
        observations, rewards, _, _, infos = env.step(
            {agent: law(observation) for agent, observation in observations.items()}
        )
    states = [bot.read() for bot in env.unwrapped.scene.bots]
    velocity, yaw_rate = env.unwrapped.scene.episode.targets[0][200]
    info = infos["bot_0"]
    assert info["yaw_rate_error"] == pytest.approx(abs(states[0].yaw_rate - yaw_rate))
    team_velocity = sum(state.forward_velocity for state in states) / len(states)
    assert info["velocity_error"] == pytest.approx(abs(team_velocity - velocity))
    assert len(set(rewards.values())) == 1  # one team reward
    env.close()


def test_the_followers_turn_after_the_front_bot():
    env = bbbench.make_parallel(TASK)
    law = SteerController("discrete", guide=SteeringTeam(env.unwrapped.scene.scenario))
    observations, _ = env.reset(seed=3)
    for _ in range(1500):
        observations, _, _, _, _ = env.step(
            {agent: law(observation) for agent, observation in observations.items()}
        )
        if not env.agents:
            break
    assert env.unwrapped.outcome.cause == ""  # up to the time limit: nothing broke
    headings = [math.atan2(*reversed(bot.read().heading)) for bot in env.unwrapped.scene.bots]
    start = math.pi / 2  # they started along +y
    assert abs(headings[0] - start) > 0.5  # the column has turned
    env.close()


def test_the_seeds_repeat_the_episode():
    parallel_seed_test(lambda: bbbench.make_parallel(TASK))


def test_team_plays_both_robots_columns_and_refuses_the_rest():
    team = load_policy("team")
    assert team.mismatch(TASK) is None
    assert team.mismatch("bbbench/Convoy-v0") is None
    assert "not a team task" in team.mismatch("bbbench/Swap-v0")
    assert "wheel-legged" in team.mismatch("bbbench/LeggedBumps-v0")


def test_team_says_which_robots_columns_it_plays(capsys):
    from bbbench.cli import main

    assert main(["eval", "team", "--task", "bbbench/Swap-v0", "--episodes", "1"]) == 2
    error = capsys.readouterr().err
    assert "two-wheel robot -> Discrete(9) or two-wheel-steer robot -> Discrete(27)" in error
    assert "Swap-v0 is not a team task" in error
    assert "Traceback" not in error

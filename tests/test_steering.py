"""The two-wheel bot that steers (`bbbench.robots.steering`): the same body and motors,
its wheels commanded apart; a robot of its own beside the published ones."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pybullet_data
import pytest
from gymnasium.utils.env_checker import check_env

from bbbench.envs.balance import BalanceEnv
from bbbench.policies.controllers.pd import PDController
from bbbench.policies.controllers.steer import SteerController
from bbbench.robots import MODEL, ROBOTS, TWO_WHEEL, TWO_WHEEL_STEER
from bbbench.robots.steering import (
    DISCRETE_ACTIONS,
    MAX_TURN_CHANGE,
    OBSERVATION_LAYOUT,
    TURN_LIMIT,
)
from bbbench.sim import World
from bbbench.tasks.commands import PiecewiseConstantTwist, PiecewiseConstantVelocity
from bbbench.tasks.reward import StayUpReward, TwistReward
from bbbench.tasks.spec import TaskSpec

TRACK = 0.24  # m between the wheels (balancebot.urdf's joints at x = -+0.12)


def test_it_is_a_robot_of_its_own_and_the_published_ones_are_unchanged():
    assert ROBOTS["two-wheel-steer"] is TWO_WHEEL_STEER
    assert TWO_WHEEL_STEER.model is MODEL  # the same body and motors
    assert str(TWO_WHEEL_STEER.action_space("discrete")) == "Discrete(27)"
    assert TWO_WHEEL_STEER.action_space("continuous").shape == (2,)
    assert TWO_WHEEL_STEER.observation_space().shape == (8,)
    names = [field.name for field in OBSERVATION_LAYOUT]
    assert names[:5] == [field.name for field in TWO_WHEEL.own_layout()]  # the shared five
    assert names[5:] == ["yaw_rate", "wheel_speed_difference", "turn_command"]
    assert str(TWO_WHEEL.action_space("discrete")) == "Discrete(9)"
    assert TWO_WHEEL.observation_space().shape == (5,)


def test_actions_decode_to_changes_of_the_forward_and_turning_commands():
    discrete = TWO_WHEEL_STEER.action_decoder("discrete")
    assert discrete(0) == (-1.0, -0.3)
    assert discrete(13) == (0.0, 0.0)  # the tutorial's "no change", not turning
    assert discrete(26) == (1.0, 0.3)
    assert discrete(np.int64(14)) == (0.0, 0.3)
    assert len(set(DISCRETE_ACTIONS)) == 27
    continuous = TWO_WHEEL_STEER.action_decoder("continuous")
    assert continuous(np.array([0.5, -1.0], dtype=np.float32)) == (0.5, -MAX_TURN_CHANGE)
    assert continuous([0.0, 0.5]) == (0.0, 0.5 * MAX_TURN_CHANGE)


@pytest.mark.parametrize(
    ("mode", "action", "expected"),
    [
        ("discrete", 27, "integer index 0..26"),
        ("discrete", -1, "integer index 0..26"),
        ("discrete", 1.5, "integer index 0..26"),
        ("continuous", [1.5, 0.0], r"two finite numbers in \[-1, 1\]"),
        ("continuous", [0.0, float("nan")], r"two finite numbers in \[-1, 1\]"),
        ("continuous", [0.5], r"shape \(2,\)"),
        ("continuous", "left", r"shape \(2,\)"),
    ],
)
def test_an_action_outside_the_space_says_what_was_expected(mode, action, expected):
    with pytest.raises(ValueError, match=expected):
        TWO_WHEEL_STEER.action_decoder(mode)(action)


def world_with_bot():
    world = World(time_step=0.01)
    world.client.setAdditionalSearchPath(pybullet_data.getDataPath())
    world.client.loadURDF("plane.urdf")
    bot = TWO_WHEEL_STEER.body(world.client)
    bot.reset(pitch=0.05)
    return world, bot


def balance_and_turn(world, bot, turn: float, steps: int) -> list:
    """PD balances the forward command towards 0.3 m/s; the turning command goes to
    `turn` after a second. The states read, one per step."""
    pd = PDController("continuous")
    decode = TWO_WHEEL_STEER.action_decoder("continuous")
    states = []
    for step in range(steps):
        state = bot.read()
        states.append(state)
        reading = (state.pitch, state.pitch_rate, state.wheel_speed)
        observation = TWO_WHEEL_STEER.observe(reading, bot.wheel_command, 0.3, state)
        forward = float(np.clip(pd.wheel_speed_change(observation), -1.0, 1.0))
        wanted = turn if step >= 100 else 0.0
        steer = float(np.clip((wanted - bot.turn_command) / MAX_TURN_CHANGE, -1.0, 1.0))
        bot.act(decode(np.array([forward, steer], dtype=np.float32)))
        world.step()
    return states


def test_it_turns_at_the_yaw_rate_its_wheels_make_and_stays_up():
    world, bot = world_with_bot()
    states = balance_and_turn(world, bot, turn=1.2, steps=400)
    world.close()
    last = states[-1]
    # Rolling without slipping: wheel radius x (right - left) / track.
    expected = MODEL.wheel_radius * 2 * 1.2 / TRACK
    assert last.yaw_rate == pytest.approx(expected, rel=0.02)
    assert last.wheel_speed_difference == pytest.approx(2 * 1.2, rel=0.02)
    assert last.turn_command == 1.2
    assert max(state.tilt for state in states) < 0.1
    headings = [math.atan2(s.heading[1], s.heading[0]) for s in states[150:160]]
    assert all(b > a for a, b in itertools.pairwise(headings))  # to the left
    assert last.forward_velocity == pytest.approx(0.3, abs=0.05)


def test_commands_are_clamped_and_nan_refused():
    world, bot = world_with_bot()
    assert bot.command_wheels(100.0, -100.0) == MODEL.wheel_speed_limit
    assert (bot.wheel_command, bot.turn_command) == (MODEL.wheel_speed_limit, -TURN_LIMIT)
    bot.act((-1.0, 0.3))
    assert bot.turn_command == pytest.approx(-TURN_LIMIT + 0.3)
    with pytest.raises(ValueError, match="NaN"):
        bot.command_wheels(0.0, float("nan"))
    bot.reset()
    assert (bot.wheel_command, bot.turn_command) == (0.0, 0.0)
    world.close()


def test_the_same_actions_read_the_same_bits_in_another_world():
    runs = []
    for _ in range(2):
        world, bot = world_with_bot()
        runs.append(balance_and_turn(world, bot, turn=-0.9, steps=160))
        world.close()
    assert runs[0] == runs[1]
    assert runs[0][-1].yaw_rate < 0  # turning right


def test_an_action_delay_holds_the_pair_of_commands_asked_before():
    world, bot = world_with_bot()
    bot.set_action_delay(3)
    for _ in range(3):
        bot.act((0.0, 0.3))
        world.step()
    assert abs(bot.read().wheel_speed_difference) < 0.05  # the servos still hold (0, 0)
    for _ in range(30):
        bot.act((0.0, 0.0))
        world.step()
    assert bot.read().wheel_speed_difference == pytest.approx(2 * 0.9, rel=0.05)
    world.close()


def test_the_robots_page_carries_its_spaces():
    from bbbench.robots.steering import interface_markdown

    page = (Path(__file__).parents[1] / "docs" / "robots.md").read_text()
    assert interface_markdown() in page
    assert "`two-wheel-steer`" in page


# -- the steering scenario, on a probe task (no steering task is published yet) ----------


def probe(**changes) -> TaskSpec:
    fields = {
        "id": "bbbench/SteerProbe-v0",
        "summary": "a probe of the steering scenario",
        "robot": "two-wheel-steer",
        "scenario": "steer",
        "command": PiecewiseConstantTwist(low=-1.0, high=1.0, yaw_low=-1.0, yaw_high=1.0),
        "reward": TwistReward(),
        **changes,
    }
    return TaskSpec(**fields)


def test_a_steering_task_plays_in_the_gymnasium_env_and_passes_its_checker():
    env = BalanceEnv(probe())
    assert env.observation_space.shape == (9,)  # the robot's 8, then the target yaw rate
    assert str(env.action_space) == "Discrete(27)"
    observation, _ = env.reset(seed=5)
    targets = env.scene.episode.targets  # (bots, steps + 1, 2): velocity, yaw rate
    assert targets.shape == (1, 1501, 2)
    assert observation[4] == np.float32(targets[0, 0, 0])  # target velocity
    assert observation[8] == np.float32(targets[0, 0, 1])  # target yaw rate
    _, reward, _, _, info = env.step(13)
    assert 0.0 <= reward <= 0.1
    assert set(info) >= {"velocity_error", "yaw_rate_error", "reward_upright"}
    env.close()
    check_env(BalanceEnv(probe(), action_mode="continuous"), skip_render_check=True)


def test_a_steering_episode_is_the_same_bits_in_another_env():
    runs = []
    for _ in range(2):
        env = BalanceEnv(probe(), action_mode="continuous")
        controller = SteerController("continuous")
        observation, _ = env.reset(seed=11)
        seen = [observation]
        for _ in range(300):
            observation, *_ = env.step(controller(observation))
            seen.append(observation)
        runs.append(np.array(seen))
        env.close()
    np.testing.assert_array_equal(runs[0], runs[1])


@pytest.mark.parametrize(
    ("changes", "expected"),
    [
        ({"robot": "two-wheel"}, "cannot play the two-wheel robot"),
        ({"command": PiecewiseConstantVelocity()}, r"commands a velocity and a yaw rate"),
        ({"reward": StayUpReward()}, "scores TwistReward"),
        ({"scenario": None, "robot": "two-wheel-steer"}, "commands a forward velocity"),
    ],
)
def test_a_steering_task_refuses_what_it_cannot_play(changes, expected):
    with pytest.raises(ValueError, match=expected):
        probe(**changes)


@pytest.mark.parametrize(("mode", "most_error"), [("discrete", 0.1), ("continuous", 0.02)])
def test_the_steering_law_balances_and_tracks_the_commanded_yaw_rate(mode, most_error):
    env = BalanceEnv(probe(), action_mode=mode)
    controller = SteerController(mode)
    for seed in (0, 1, 2):
        observation, _ = env.reset(seed=seed)
        errors = []
        for _ in range(1500):
            observation, _, terminated, _, info = env.step(controller(observation))
            assert not terminated
            errors.append(info["yaw_rate_error"])
        assert np.mean(errors) < most_error
    env.close()


def test_the_twist_reward_pays_each_tracked_term_and_never_costs():
    reward = TwistReward()
    assert sum(reward.terms(0.0, 0.0, 0.0)) == pytest.approx(0.1)
    assert sum(reward.terms(0.0, 0.0, 3.0)) == pytest.approx(0.01 + 0.09 * 0.5)
    assert sum(reward.terms(0.0, 3.0, 3.0)) == pytest.approx(0.01)
    assert sum(reward.terms(1.0, 0.0, 0.0)) == 0.0  # fallen over: nothing, never less
    assert reward.terms(0.0, 0.0, 0.5)[1] < reward.terms(0.0, 0.0, 0.2)[1]
    with pytest.raises(ValueError, match="yaw_share"):
        TwistReward(yaw_share=1.5)


def test_a_twist_command_holds_each_pair_for_its_drawn_duration():
    command = PiecewiseConstantTwist(low=0.2, high=0.8, yaw_low=-2.0, yaw_high=2.0)
    targets = command.targets(np.random.default_rng(0), 1500, 0.01)
    assert len(targets) == 1501
    velocities, yaw_rates = zip(*targets, strict=True)
    assert min(velocities) >= 0.2
    assert max(velocities) <= 0.8
    assert min(yaw_rates) >= -2.0
    assert max(yaw_rates) <= 2.0
    changes = [i for i in range(1, 1501) if targets[i] != targets[i - 1]]
    assert all(200 <= b - a <= 500 for a, b in itertools.pairwise(changes))  # 2-5 s
    assert command.top_target == 0.8
    with pytest.raises(ValueError, match="yaw_low <= yaw_high"):
        PiecewiseConstantTwist(yaw_low=1.0, yaw_high=-1.0)

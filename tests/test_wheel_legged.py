"""The wheel-legged robot: pybullet uses the file's values, its readings mean what they say,
its actions are checked or clipped as documented, and it plays a task through the suite's
env like the two-wheel bot."""

from __future__ import annotations

import inspect
import json
import math
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from stable_baselines3 import PPO
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import bbbench.robots.wheel_legged as wheel_legged
from bbbench.envs.balance import BalanceEnv
from bbbench.robots import ROBOTS, WHEEL_LEGGED
from bbbench.robots.layout import SHARED_FIELDS
from bbbench.robots.wheel_legged import (
    LEGGED_MODEL,
    WheelLeggedBot,
    decode,
    facts_markdown,
    interface_markdown,
)
from bbbench.sim import World
from bbbench.tasks.spec import TaskSpec
from bbbench.terrain import FlatGround, load_ground

LEGGED_TASK = TaskSpec(
    id="bbbench/LeggedTest-v0", summary="a wheel-legged test task", robot="wheel-legged"
)


@pytest.fixture
def world_and_bot():
    world = World(time_step=0.01)
    load_ground(world.client, FlatGround())
    bot = WheelLeggedBot(world.client)
    yield world, bot
    world.close()


def test_the_facts_table_is_read_from_the_urdf_and_written_in_the_docstring():
    table = facts_markdown()
    assert table in wheel_legged.__doc__
    assert LEGGED_MODEL.wheel_radius == 0.1  # the two-wheel bot's family
    assert LEGGED_MODEL.mass == pytest.approx(1.2)
    assert LEGGED_MODEL.standing == pytest.approx((0.6, -1.2, 0.6, -1.2))  # range centres
    assert "| hip range | -0.4 to 1.6 rad (+: thigh forward) |" in table


def test_pybullet_uses_the_files_masses_inertias_friction_and_limits(world_and_bot):
    world, bot = world_and_bot
    client = world.client
    torso = client.getDynamicsInfo(bot.body, -1)
    assert torso[0] == pytest.approx(0.8)
    assert torso[2] == pytest.approx((0.00213333, 0.00437333, 0.00309333))  # from the file
    for joint in bot.wheel_joints:
        mass, friction, inertia = client.getDynamicsInfo(bot.body, joint)[:3]
        assert (mass, friction) == pytest.approx((0.1, 0.8))
        assert inertia[0] == pytest.approx(0.1 * 0.1**2 / 2)
    for leg, joint in zip(LEGGED_MODEL.legs, bot.leg_joints, strict=True):
        info = client.getJointInfo(bot.body, joint)
        assert (info[8], info[9], info[10], info[11]) == (
            leg.lower,
            leg.upper,
            leg.effort,
            leg.velocity,
        )


def test_reset_stands_the_robot_with_its_wheels_on_the_ground(world_and_bot):
    world, bot = world_and_bot
    for pitch in (-0.3, 0.0, 0.2):
        bot.reset(pitch=pitch, xy=(1.0, 2.0))
        for joint in bot.wheel_joints:
            assert world.client.getLinkState(bot.body, joint)[0][2] == pytest.approx(0.1)
        state = bot.read()
        assert state.pitch == pytest.approx(pitch)
        assert state.axle[:2] == pytest.approx((1.0, 2.0))
        assert state.leg_angles == pytest.approx(LEGGED_MODEL.standing)


def test_roll_is_positive_leaning_right_and_pitch_positive_leaning_forward(world_and_bot):
    world, bot = world_and_bot
    client = world.client
    bot.reset()
    centre = client.getBasePositionAndOrientation(bot.body)[0]
    # A lean to the right: a positive turn about the forward axis (+y).
    client.resetBasePositionAndOrientation(
        bot.body, centre, client.getQuaternionFromEuler((0.0, 0.2, 0.0))
    )
    state = bot.read()
    assert state.roll == pytest.approx(0.2)
    assert state.pitch == pytest.approx(0.0, abs=1e-9)


def test_leg_targets_are_reached_and_those_outside_the_range_are_clipped(world_and_bot):
    world, bot = world_and_bot
    bot.reset()
    height = bot.read().height
    crouch = (1.0, -2.0, 1.0, -2.0)
    for _ in range(100):
        bot.act((*crouch, 0.0, 0.0))
        world.step()
    state = bot.read()
    assert state.leg_angles == pytest.approx(crouch, abs=0.03)  # soft servos sag a little
    assert state.height < height - 0.05  # the torso came down
    far = (9.0, -9.0, -9.0, 9.0)  # every one beyond its joint's range
    bot.act((*far, 0.0, 0.0))
    ends = tuple(
        leg.upper if value > 0 else leg.lower
        for leg, value in zip(LEGGED_MODEL.legs, far, strict=True)
    )
    assert bot.leg_targets == ends
    for _ in range(100):
        bot.act((*far, 0.0, 0.0))
        world.step()
    for leg, angle in zip(LEGGED_MODEL.legs, bot.read().leg_angles, strict=True):
        assert leg.lower - 0.05 <= angle <= leg.upper + 0.05


def test_the_wheels_drive_forward_and_their_commands_are_clamped(world_and_bot):
    world, bot = world_and_bot
    bot.reset()
    for _ in range(40):
        command = bot.act((*LEGGED_MODEL.standing, 1.0, 1.0))
    assert command == bot.wheel_command == LEGGED_MODEL.wheel_speed_limit
    world.step()
    assert bot.read().wheel_speed > 0  # both wheels turn forward with a positive command


def test_actions_decode_to_targets_and_changes_or_say_what_was_expected():
    hip, knee = LEGGED_MODEL.legs[:2]
    decoded = decode(np.array([-1, 1, 0, 0, 0.5, -1], dtype=np.float32))
    assert decoded == pytest.approx((hip.lower, knee.upper, 0.6, -1.2, 0.5, -1.0))
    assert decode([2.0, 0, 0, 0, 0, 0])[0] == pytest.approx(hip.upper + hip.half_range)
    for wrong in ([0, 0, 0, 0, 1.5, 0], [0.0] * 5, [math.nan] * 6, "six"):
        with pytest.raises(ValueError, match="expected 6 finite numbers"):
            decode(wrong)


def test_the_layout_begins_with_the_shared_values_and_says_its_units():
    layout = WHEEL_LEGGED.layout()
    assert tuple(field.name for field in layout[:5]) == SHARED_FIELDS
    assert [field.name for field in layout[5:9]] == [
        f"{name}_angle" for name in wheel_legged.LEG_JOINT_NAMES
    ]
    assert (layout[13].name, layout[13].unit) == ("roll", "rad")
    # Equal each call, and a new object: a space carries its own random generator.
    assert WHEEL_LEGGED.observation_space() == WHEEL_LEGGED.observation_space()
    assert WHEEL_LEGGED.observation_space() is not WHEEL_LEGGED.observation_space()
    assert WHEEL_LEGGED.observation_space(height_scan=True).shape == (len(layout) + 11,)
    assert ROBOTS["wheel-legged"] is WHEEL_LEGGED


def test_a_wheel_legged_task_passes_gymnasiums_and_sb3s_checkers():
    check_env(BalanceEnv(LEGGED_TASK), skip_render_check=True)
    sb3_check_env(BalanceEnv(LEGGED_TASK))
    env = BalanceEnv(LEGGED_TASK)
    assert env.action_mode == "continuous"  # the robot's only mode is the default
    observation, _ = env.reset(seed=3)
    assert env.observation_space.contains(observation)
    with pytest.raises(ValueError, match="for the wheel-legged robot, got 'discrete'"):
        BalanceEnv(LEGGED_TASK, action_mode="discrete")


def test_a_task_names_its_robot_and_the_robot_is_in_its_fingerprint():
    assert LEGGED_TASK.robot_model is WHEEL_LEGGED
    two_wheel = TaskSpec(id="bbbench/LeggedTest-v0", summary="a wheel-legged test task")
    assert two_wheel.spec_hash != LEGGED_TASK.spec_hash
    with pytest.raises(ValueError, match="robot must be one of 'two-wheel', 'wheel-legged'"):
        TaskSpec(id="bbbench/X-v0", summary="x", robot="three-wheel")


def test_same_seed_and_actions_give_the_same_observations():
    def play() -> list[bytes]:
        env = BalanceEnv(LEGGED_TASK)
        observation, _ = env.reset(seed=11)
        rng = np.random.default_rng(0)
        seen = [observation.tobytes()]
        for _ in range(200):
            observation, *_ = env.step(rng.uniform(-1, 1, 6).astype(np.float32))
            seen.append(observation.tobytes())
        env.close()
        return seen

    assert play() == play()


# -- the robot's tasks through the suite ------------------------------------------------

LEGGED_TASKS = (
    "bbbench/LeggedFlatBalance-v0",
    "bbbench/LeggedVelocityTracking-v0",
    "bbbench/LeggedBumps-v0",
    "bbbench/LeggedObstacles-v0",
)


def test_the_legged_tasks_are_the_two_wheel_rows_with_the_other_robot():
    import bbbench

    alone = [t for t in bbbench.list_tasks() if bbbench.spec(t).robots == ()]  # not a team
    assert [t for t in alone if bbbench.spec(t).robot == "wheel-legged"] == sorted(LEGGED_TASKS)
    flat, two_wheel = bbbench.spec(LEGGED_TASKS[0]), bbbench.spec("bbbench/FlatBalance-v1")
    assert (flat.command, flat.reward, flat.eval_seeds) == (
        two_wheel.command,
        two_wheel.reward,
        two_wheel.eval_seeds,
    )
    bumps = bbbench.spec("bbbench/LeggedBumps-v0")
    assert bumps.terrain.generator.extra_height == 0.25  # hills over twice Bumps-v2's
    env = gymnasium.make("bbbench/LeggedBumps-v0")
    assert env.unwrapped.action_mode == "continuous"
    assert env.spec.kwargs["difficulty"] == 0.85
    check_env(env.unwrapped, skip_render_check=True)


def test_every_legged_task_documents_the_robots_spaces_and_docs_carry_the_tables():
    from bbbench.envs import task_envs as tasks

    for task_id in LEGGED_TASKS:
        name = task_id.removeprefix("bbbench/").removesuffix("-v0")
        assert interface_markdown() in inspect.cleandoc(getattr(tasks, f"{name}Env").__doc__)
    robots_md = (Path(__file__).parents[1] / "docs" / "robots.md").read_text()
    assert facts_markdown() in robots_md
    assert interface_markdown() in robots_md
    table = interface_markdown()
    for i, field in enumerate(WHEEL_LEGGED.layout()):
        assert f"| {i} | {field.name} | " in table


def test_the_classical_controller_balances_where_pd_cannot_play():
    from bbbench.policies import load_policy
    from bbbench.policies.controllers.legged import LeggedController, balance_pitch

    env = BalanceEnv("bbbench/LeggedFlatBalance-v0")
    controller = LeggedController()
    for seed in env.task.eval_seeds[:3]:
        observation, _ = env.reset(seed=seed)
        for _ in range(1500):
            observation, _, fell, _, _ = env.step(controller(observation))
            assert not fell
        assert abs(env.scene.bots[0].read().forward_velocity) < 0.05  # in place
    # Standing, the legs are forward of the torso's axis: balanced leaning back a little.
    assert -0.05 < balance_pitch(LEGGED_MODEL, *LEGGED_MODEL.standing[:2]) < 0
    assert load_policy("pd").mismatch("bbbench/LeggedBumps-v0") == (
        "bbbench/LeggedBumps-v0 plays the wheel-legged robot; pd controls the two-wheel robot"
    )
    assert load_policy("legged").mismatch("bbbench/Bumps-v2") is not None


def _legged_zip(path: Path) -> Path:
    import bbbench

    model = PPO("MlpPolicy", bbbench.make_vec(LEGGED_TASKS[0], n_envs=1), n_steps=32, batch_size=32)
    model.learn(32)
    model.save(path)
    return path


def test_a_policy_of_one_robot_on_the_others_task_is_exit_2_naming_both_layouts(tmp_path, capsys):
    from bbbench.cli import main
    from bbbench.policies.registry import REFERENCE_POLICY

    assert main(["eval", str(REFERENCE_POLICY), "--task", "bbbench/LeggedBumps-v0"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert "wants Box(17,) (wheel-legged: pitch, pitch_rate" in err
    assert "observes the two-wheel robot's Box(5,) (two-wheel: pitch" in err
    assert "fits bbbench/Bumps-v2, bbbench/FlatBalance-v1" in err

    legged = _legged_zip(tmp_path / "legged.zip")
    assert main(["eval", str(legged), "--task", "bbbench/Bumps-v2"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert "wants Box(5,) (two-wheel: pitch" in err
    assert "observes the wheel-legged robot's Box(17,)" in err
    assert f"fits {', '.join(sorted(LEGGED_TASKS))}" in err


def test_eval_and_rollout_play_the_legged_tasks(tmp_path, capsys):
    from bbbench.cli import main

    legged = _legged_zip(tmp_path / "legged.zip")
    out = tmp_path / "results.json"
    argv = ["eval", str(legged), "--episodes", "2", "--workers", "1", "--json", str(out)]
    assert main(argv) == 0
    played = [block["task"] for block in json.loads(out.read_text())["tasks"]]
    assert played == sorted(LEGGED_TASKS)  # every task it fits, and only those
    assert (
        main(["rollout", "--task", LEGGED_TASKS[2], "--policy", "legged", "--episodes", "1"]) == 0
    )
    assert "bbbench/LeggedBumps-v0: 1 episode(s) of the 'legged' policy" in capsys.readouterr().out


def test_training_picks_the_robots_action_mode_or_says_what_to_use():
    from bbbench.training import check_request

    assert check_request([LEGGED_TASKS[0]], "ppo", None, None)[2] == "continuous"
    assert check_request(["bbbench/FlatBalance-v1"], "ppo", None, None)[2] == "discrete"
    with pytest.raises(ValueError, match="takes continuous actions, not discrete"):
        check_request([LEGGED_TASKS[0]], "dqn", None, None)
    with pytest.raises(ValueError, match="one policy trains on one robot's tasks"):
        check_request([LEGGED_TASKS[0], "bbbench/FlatBalance-v1"], "ppo", None, None)


def test_the_board_ranks_the_legged_tasks_on_a_track_of_their_own():
    import bbbench
    from bbbench.leaderboard.board import Board
    from bbbench.tasks.tracks import track_of

    assert {track_of(bbbench.spec(t)).name for t in LEGGED_TASKS} == {"wheel-legged"}
    assert track_of(bbbench.spec("bbbench/Bumps-v2")).name == "single"
    assert track_of(bbbench.spec("bbbench/MultiBalance-v1")).name == "multi"
    assert track_of(bbbench.spec("bbbench/LeggedBumps-v0")).profiled_on == (
        "bbbench/LeggedVelocityTracking-v0"
    )
    assert Board().ranked("wheel-legged") == sorted(LEGGED_TASKS)
    assert not set(Board().ranked("single")) & set(LEGGED_TASKS)


def test_a_sweep_of_the_legged_controller_plays_the_robots_own_profile_task(tmp_path, capsys):
    from bbbench.cli import main

    out = tmp_path / "sweep.json"
    argv = ["sweep", "legged", "--axis", "push", "--values", "0,1", "--episodes", "1"]
    assert main([*argv, "--workers", "1", "--json", str(out)]) == 0
    (entry,) = json.loads(out.read_text())["policies"]
    assert [task["task"] for task in entry["tasks"]] == ["bbbench/LeggedVelocityTracking-v0"]


# Both checkers and 20000 random steps on every legged task: tests/test_suite.py.
@pytest.mark.parametrize("task_id", LEGGED_TASKS)
def test_every_legged_task_shares_the_robots_spaces(task_id):
    env = gymnasium.make(task_id).unwrapped
    assert env.observation_space == WHEEL_LEGGED.observation_space()
    assert env.action_space == WHEEL_LEGGED.action_space("continuous")

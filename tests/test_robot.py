"""The robot: pybullet really uses the model's values, and the readings mean what they say."""

from __future__ import annotations

import dataclasses
import math

import pybullet
import pytest

from bbbench.robots import FALL_TILT, MODEL, ROBOTS, BalanceBot
from bbbench.sim import World
from bbbench.tasks import SUITE
from bbbench.tasks.commands import ConstantVelocity, PiecewiseConstantVelocity
from bbbench.tasks.reward import has_fallen
from bbbench.terrain import FlatGround, load_ground


@pytest.fixture
def world_and_bot():
    world = World(time_step=0.01)
    ground = load_ground(world.client, FlatGround()).body
    bot = BalanceBot(world.client)
    yield world, bot, ground
    world.close()


def test_the_model_is_the_tutorials_with_finite_motors():
    assert MODEL.wheel_radius == 0.1
    assert MODEL.wheel_speed_limit == 24.6
    assert 0 < MODEL.motor_torque_limit < 10  # finite, not pybullet's default 100000
    assert MODEL.top_speed == pytest.approx(2.46)


def test_pybullet_uses_the_files_masses_inertias_and_friction(world_and_bot):
    world, bot, ground = world_and_bot
    client = world.client
    torso = client.getDynamicsInfo(bot.body, -1)
    assert torso[0] == pytest.approx(0.8)
    assert torso[2] == pytest.approx((0.0108333, 0.0133333, 0.0028333))  # from the file
    for joint in bot.wheel_joints:
        mass, friction, inertia = client.getDynamicsInfo(bot.body, joint)[:3]
        assert mass == pytest.approx(0.1)
        assert friction == pytest.approx(0.8)  # <contact><lateral_friction>
        assert inertia[0] == pytest.approx(0.1 * 0.1**2 / 2)  # axial m r^2 / 2
        info = client.getJointInfo(bot.body, joint)
        assert info[10] == MODEL.motor_torque_limit  # jointMaxForce
        assert info[11] == MODEL.wheel_speed_limit  # jointMaxVelocity
    assert client.getDynamicsInfo(ground, -1)[1] == pytest.approx(1.0)


def test_reset_puts_the_wheels_on_the_ground_at_any_lean(world_and_bot):
    world, bot, _ = world_and_bot
    for pitch in (-0.3, 0.0, 0.2):
        bot.reset(pitch=pitch)
        wheel_z = world.client.getLinkState(bot.body, bot.wheel_joints[0])[0][2]
        assert wheel_z == pytest.approx(MODEL.wheel_radius, abs=1e-9)
        assert bot.pitch == pytest.approx(pitch)


def drive(world, bot, speed: float, steps: int = 20):
    for i in range(steps):
        bot.command_wheel_speed(min(speed, float(i)))
        world.client.stepSimulation()
    return bot.read()


@pytest.mark.parametrize("yaw", [0.0, math.pi / 2, -2.0])
def test_positive_wheel_speed_drives_forward_whatever_the_heading(world_and_bot, yaw):
    world, bot, _ = world_and_bot
    bot.reset(yaw=yaw)
    state = drive(world, bot, 5.0)
    # The servo holds its speed to 0.3% (measured) with the world's 10 solver iterations.
    assert state.wheel_speed == pytest.approx(5.0, rel=0.01)
    left, right = bot.wheel_speeds  # both forward-positive, though the axes are opposite
    assert left == pytest.approx(5.0, rel=0.01)
    assert right == pytest.approx(5.0, rel=0.01)
    assert state.forward_velocity > 0.2
    # Accelerating forward pitches the torso back; the reading does not depend on heading
    # (to Bullet's contact solver, which works in world axes: 0.1% apart at yaw -2).
    assert state.pitch < -0.1
    bot.reset(yaw=0.0)
    reference = drive(world, bot, 5.0)
    assert state.pitch == pytest.approx(reference.pitch, rel=0.01)
    assert state.forward_velocity == pytest.approx(reference.forward_velocity, rel=0.01)


def test_pitch_rate_is_the_derivative_of_pitch(world_and_bot):
    world, bot, _ = world_and_bot
    bot.reset(pitch=0.05)
    previous = bot.read().pitch
    for _ in range(30):  # falling forward
        world.client.stepSimulation()
        state = bot.read()
        # Equal but for the solver's position correction (2e-6 relative, measured).
        assert state.pitch_rate == pytest.approx((state.pitch - previous) / 0.01, rel=1e-4)
        previous = state.pitch
    assert state.pitch_rate > 0


def test_forward_velocity_matches_rolling_without_slip(world_and_bot):
    world, bot, _ = world_and_bot
    bot.reset()
    state = drive(world, bot, 5.0)
    rolling = MODEL.wheel_radius * (state.wheel_speed + state.pitch_rate)
    # Measured: the sphere-collision wheels lose 0.74% to rolling under this hard
    # acceleration (cylinders 0.01%); the bot rests at its full 0.1 m axle height.
    assert state.forward_velocity == pytest.approx(rolling, rel=0.01)


def test_fall_is_a_tilt_past_the_limit_not_a_height(world_and_bot):
    world, bot, _ = world_and_bot
    bot.reset(pitch=0.3)
    assert not has_fallen(bot.read())
    for _ in range(300):
        world.client.stepSimulation()
    state = bot.read()
    assert state.tilt > FALL_TILT
    assert has_fallen(state)
    # Upright on raised ground (a step, a hill) is not a fall.
    bot.reset(ground_height=0.5)
    assert not has_fallen(bot.read())


def test_wheel_command_is_clamped_and_nan_refused(world_and_bot):
    _, bot, _ = world_and_bot
    assert bot.command_wheel_speed(100.0) == MODEL.wheel_speed_limit
    assert bot.command_wheel_speed(-100.0) == -MODEL.wheel_speed_limit
    assert bot.wheel_command == -MODEL.wheel_speed_limit
    with pytest.raises(ValueError, match="NaN"):
        bot.command_wheel_speed(float("nan"))


def test_a_world_never_uses_the_global_connection():
    world = World(time_step=0.01)
    assert not pybullet.isConnected(0) or world.client_id != 0
    assert world.client.getPhysicsEngineParameters()["fixedTimeStep"] == 0.01
    world.close()


@pytest.mark.parametrize("name", ["two-wheel", "wheel-legged", "two-wheel-steer"])
def test_a_task_may_not_ask_for_more_than_its_robots_top_speed(name):
    robot = ROBOTS[name]
    assert robot.top_speed == robot.model.wheel_speed_limit * robot.model.wheel_radius
    fast = dataclasses.replace(SUITE["bbbench/VelocityTracking-v1"], robot=name)
    too_fast = PiecewiseConstantVelocity(low=-1.0, high=robot.top_speed + 0.01)
    with pytest.raises(ValueError, match=f"beyond the {name} robot's top speed"):
        dataclasses.replace(fast, command=too_fast)
    at_top = ConstantVelocity(velocity=-robot.top_speed)
    assert dataclasses.replace(fast, command=at_top).command.top_target == robot.top_speed


@pytest.mark.parametrize("speed", [float("nan"), float("inf")])
def test_a_command_refuses_a_speed_that_is_not_a_number(speed):
    with pytest.raises(ValueError, match="finite speed"):
        ConstantVelocity(velocity=speed)
    with pytest.raises(ValueError, match="finite speed"):
        PiecewiseConstantVelocity(low=-1.0, high=speed)


def test_a_robot_lacking_a_declared_part_is_refused_when_registered():
    from bbbench.robots import TWO_WHEEL
    from bbbench.robots.robot import Robot, registered

    class Half(Robot):
        name = "half"
        summary = "a robot with no controller and no body"
        model = MODEL
        action_modes = ("discrete",)

    with pytest.raises(TypeError, match=r"robot Half lacks controller, body\(\), action_space"):
        registered([Half()])
    with pytest.raises(ValueError, match="two robots are called 'two-wheel'"):
        registered([TWO_WHEEL, TWO_WHEEL])
    assert registered(ROBOTS.values()) == ROBOTS

"""The waypoint tasks (`bbbench.tasks.scenarios.waypoints`): the steering bot drives
through a seeded course; the steering law (`steer`) gets round it."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

import bbbench
from bbbench.envs.balance import BalanceEnv
from bbbench.evaluation.harness import play_draws
from bbbench.policies import classical_controller, load_policy
from bbbench.policies.controllers.steer import SteerController
from bbbench.tasks.scenarios.waypoints import (
    COURSE_POINTS,
    COURSE_RADIUS,
    MIN_LEG,
    REACH,
    SCORED_AS_PUBLISHED,
    Waypoints,
    draw_course,
)

WAYPOINTS = ("bbbench/Waypoints-v0", "bbbench/WaypointsBumps-v0")


def test_a_course_lies_in_its_disc_with_legs_at_least_the_least_leg():
    course = draw_course(np.random.default_rng(3))
    assert len(course) == COURSE_POINTS
    points = np.array([(0.0, 0.0), *course])
    assert np.all(np.hypot(points[:, 0], points[:, 1]) <= COURSE_RADIUS)
    assert np.all(np.hypot(*np.diff(points, axis=0).T) >= MIN_LEG)
    assert course == draw_course(np.random.default_rng(3))
    assert course != draw_course(np.random.default_rng(4))


@pytest.mark.parametrize("task_id", WAYPOINTS)
def test_the_course_comes_from_the_episode_seed(task_id):
    env = bbbench.make(task_id)
    env.reset(seed=7)
    first = list(env.unwrapped.scene.scenario.course)
    env.reset(seed=8)
    assert env.unwrapped.scene.scenario.course != first
    env.reset(seed=7)
    assert env.unwrapped.scene.scenario.course == first
    env.close()


def test_the_goal_is_observed_in_the_bot_frame_and_moves_on_when_reached():
    env = bbbench.make("bbbench/Waypoints-v0")
    observation, _ = env.reset(seed=7)
    scenario = env.unwrapped.scene.scenario
    gx, gy = scenario.course[0]
    # The bot starts at the origin heading along +y: a goal to its left has a + sine.
    assert observation[8] == pytest.approx(np.hypot(gx, gy), abs=0.02)
    assert observation[9] == pytest.approx(gy / np.hypot(gx, gy), abs=0.02)
    assert observation[10] == pytest.approx(-gx / np.hypot(gx, gy), abs=0.02)
    assert observation[9] ** 2 + observation[10] ** 2 == pytest.approx(1.0, abs=1e-5)
    law = SteerController.for_scenario(Waypoints)
    reached = []
    for step in range(1500):
        observation, _, terminated, _, info = env.step(law(observation))
        assert not terminated
        if info["waypoints_per_minute"]:
            assert info["waypoints_per_minute"] == 6000.0  # 100 steps a second
            reached.append(step)
            assert info["goal_distance"] > REACH  # the next one's distance
    env.close()
    assert len(reached) >= 2
    assert scenario.goal == len(reached)


def test_driving_at_the_goal_earns_more_than_driving_past_it():
    env = bbbench.make("bbbench/Waypoints-v0")
    law = SteerController.for_scenario(Waypoints)
    blind = SteerController("discrete", guide=lambda o: (float(o[4]), 0.0))  # straight on
    returns = []
    for policy in (law, blind):
        observation, _ = env.reset(seed=7)
        total = 0.0
        for _ in range(600):
            observation, reward, terminated, _, _ = env.step(policy(observation))
            total += reward
            if terminated:
                break
        returns.append(total)
    env.close()
    assert returns[0] > 1.5 * returns[1]


def test_the_steering_law_plays_only_the_steering_robot():
    policy = load_policy("steer")
    assert policy.mismatch("bbbench/Waypoints-v0") is None
    assert policy.mismatch("bbbench/SteerTracking-v0") is None
    assert "two-wheel robot" in policy.mismatch("bbbench/VelocityTracking-v1")
    assert "steer controls the two-wheel-steer robot" in load_policy("steer").mismatch(
        "bbbench/FlatBalance-v1"
    )


STEERING_TASKS = [t for t in bbbench.list_tasks() if bbbench.spec(t).robot == "two-wheel-steer"]


@pytest.mark.parametrize("task_id", STEERING_TASKS)
def test_a_rendered_episode_shows_its_goals_and_plays_as_an_unrendered_one(task_id):
    """Every steering task, under its classical controller; where the task has goals
    (the waypoint tasks, Swap-v0), the frames show them where they are."""

    def play(render_mode):
        multi = bbbench.spec(task_id).multi_agent
        env = (bbbench.make_parallel if multi else bbbench.make)(task_id, render_mode=render_mode)
        actor = load_policy(classical_controller(task_id)).actor(task_id)
        observations, _ = env.reset(seed=2**31)
        rows = []
        for step in range(120):
            if multi:
                actions = actor(np.stack(list(observations.values())))
                observations, *_ = env.step(dict(zip(env.agents, actions, strict=True)))
                rows.append(np.stack(list(observations.values())))
            else:
                observations, *_ = env.step(actor(observations[None])[0])
                rows.append(observations)
            if render_mode and step % 40 == 0:
                assert env.render().shape[2] == 3
        return np.stack(rows), env

    plain, _ = play(None)
    drawn, env = play("rgb_array")
    np.testing.assert_array_equal(plain, drawn)
    scenario = env.unwrapped.scene.scenario
    if not hasattr(scenario, "markers"):
        return  # a commanded task: no goals to show
    client = env.unwrapped.scene.world.client
    shown = [client.getBasePositionAndOrientation(body)[0][:2] for body in scenario.markers]
    goals = scenario.goals if hasattr(scenario, "goals") else scenario.course[scenario.goal :]
    np.testing.assert_allclose(shown, goals[: len(shown)], atol=1e-9)


# steer's episodes on the published rows, as the board recorded them before it moved to
# their v1 (the file's "source" says where from).
PUBLISHED_FILE = Path(__file__).parent / "data" / "steer_waypoints_published.json"
PUBLISHED = json.loads(PUBLISHED_FILE.read_text())


@pytest.mark.parametrize("task_id", WAYPOINTS)
def test_the_published_rows_replay_their_episodes_under_the_step_protocol(task_id):
    """Waypoints' published rows were scored before they were observed; under the one
    step protocol they keep it (`SCORED_AS_PUBLISHED`): `steer`'s recorded episodes,
    each reaching waypoints, replay in full, their metrics too."""
    stored = PUBLISHED["episodes"][task_id]
    assert all(episode["waypoints_per_minute"] > 0.0 for episode in stored)
    draws = [(load_policy("steer"), bbbench.spec(task_id), e["seed"]) for e in stored]
    assert [episode.record() for episode in play_draws(draws, workers=1)] == stored


def test_a_new_row_scores_a_reached_waypoint_in_the_step_that_reaches_it():
    published = bbbench.spec("bbbench/Waypoints-v0")
    assert published.id in SCORED_AS_PUBLISHED
    fresh = dataclasses.replace(published, id="bbbench/WaypointsProbe-v0")
    reached = []
    for task in (published, fresh):
        env = BalanceEnv(task)
        law = SteerController.for_scenario(Waypoints)
        observation, _ = env.reset(seed=7)
        for step in range(1, 1501):
            observation, _, _, _, info = env.step(law(observation))
            if info["waypoints_per_minute"]:
                reached.append(step)
                break
        env.close()
    assert reached[1] == reached[0] - 1  # a step earlier than the published rows say

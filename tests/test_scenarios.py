"""Scenarios: each task's rules in one class (`bbbench.tasks.scenarios`).

The throwaway scenario here follows docs/architecture.md, "How to add a scenario" and
"How to add a multi-bot task with a shared object", step by step: a class on `Scenario`,
registered in `SCENARIOS`, named by a task spec, played by the multi-bot env.
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import cloudpickle
import numpy as np
import pybullet
import pytest
from pettingzoo.test import parallel_api_test

import bbbench
from bbbench.envs.balance import BalanceEnv
from bbbench.envs.multi import MultiBalanceEnv
from bbbench.evaluation.play import MultiEpisode
from bbbench.robots.layout import ObservationField
from bbbench.tasks.group import Group
from bbbench.tasks.scenarios import SCENARIOS, Crossing, Scenario, Solo
from bbbench.tasks.spec import TaskSpec
from bbbench.tasks.suite import SUITE
from bbbench.tasks.tracks import track_of

REPO = Path(__file__).resolve().parent.parent
BALL_RADIUS = 0.15  # m
PARKED = (0.0, -500.0, 5.0)  # where the ball waits between episodes, clear of everything


class Ball(Crossing):
    """The guide's example: Crossing's bots with a ball among them. The ball rests at a
    random point near the centre of the circle; each bot also observes the ball's offset
    in its own frame, and the episode reports the mean distance of the bots to it."""

    name = "ball"
    summary = "bots whose paths cross, with a ball among them"
    metrics = ("velocity_error", "ball_distance")

    def __init__(self, task) -> None:
        super().__init__(task)
        reach = task.group.neighbour_range
        self.layout = (
            *self.layout,
            ObservationField("ball_right", "m", -reach, reach, "the ball: to the right"),
            ObservationField("ball_forward", "m", -reach, reach, "the ball: ahead"),
        )
        self.ball = None

    def build(self, client, bots) -> None:
        shape = client.createCollisionShape(pybullet.GEOM_SPHERE, radius=BALL_RADIUS)
        self.ball = client.createMultiBody(baseMass=0.5, baseCollisionShapeIndex=shape)
        self._client = client

    def move_clear(self, scene) -> None:
        self._client.resetBasePositionAndOrientation(self.ball, PARKED, (0, 0, 0, 1))

    def place(self, scene, rng) -> None:
        x, y = rng.uniform(-0.5, 0.5, size=2)
        self.centre = (float(x), float(y))
        height = scene.ground.spawn_height(x, y) + BALL_RADIUS
        self._client.resetBasePositionAndOrientation(self.ball, (x, y, height), (0, 0, 0, 1))
        self._client.resetBaseVelocity(self.ball, (0, 0, 0), (0, 0, 0))

    def _ball(self) -> complex:
        (x, y, _), _ = self._client.getBasePositionAndOrientation(self.ball)
        return complex(x, y)

    def observe(self, scene, states, commands, targets, step):
        rows = super().observe(scene, states, commands, targets, step)
        ball = self._ball()
        extra = []
        for state in states:
            forward_x, forward_y = state.heading
            offset = (ball - complex(*state.position[:2])) * complex(forward_y, forward_x)
            reach = self.group.neighbour_range
            extra.append([min(max(v, -reach), reach) for v in (offset.real, offset.imag)])
        return np.hstack([rows, np.array(extra, dtype=np.float32)])

    def outcome(self, agents, states, targets, seed):
        outcome = super().outcome(agents, states, targets, seed)
        ball = self._ball()
        for info, state in zip(outcome.infos, states, strict=True):
            info["ball_distance"] = abs(ball - complex(*state.position[:2]))
        return outcome


@pytest.fixture
def ball_task(monkeypatch) -> TaskSpec:
    monkeypatch.setitem(SCENARIOS, "ball", Ball)
    return dataclasses.replace(
        SUITE["bbbench/MultiBalance-v1"], id="bbbench/BallCrossing-v0", scenario="ball"
    )


def test_every_task_before_the_teams_plays_solo_or_crossing():
    """The tasks published before the scenario seam name none, and play the scenario
    their group implies; the team tasks and the steering robot's tasks name theirs."""
    for task in SUITE.values():
        if task.robot == "two-wheel-steer":
            assert task.scenario in ("steer", "waypoints", "swap", "convoy-turns", "rendezvous")
        elif task.coupling is None:
            assert task.scenario_class is (Crossing if task.multi_agent else Solo)
        else:
            assert task.scenario in ("beam-carry", "convoy", "mixed-beam-carry")


def test_naming_the_implied_scenario_leaves_the_fingerprint():
    task = SUITE["bbbench/MultiBalance-v1"]
    named = dataclasses.replace(task, scenario="crossing")
    assert named.spec_hash == task.spec_hash
    assert dataclasses.replace(task, scenario="solo", group=None).spec_hash != task.spec_hash


def test_a_scenario_given_a_robot_it_cannot_play_names_both(monkeypatch):
    class TwoWheelOnly(Crossing):
        name = "two-wheel-only"
        robots = ("two-wheel",)

    monkeypatch.setitem(SCENARIOS, "two-wheel-only", TwoWheelOnly)
    task = SUITE["bbbench/MultiBalance-v1"]
    with pytest.raises(ValueError, match=r"'two-wheel-only' scenario cannot play the wheel-legged"):
        dataclasses.replace(task, scenario="two-wheel-only", robot="wheel-legged")
    with pytest.raises(ValueError, match=r"scenario must be one of 'solo', 'crossing'"):
        dataclasses.replace(task, scenario="carry")
    with pytest.raises(ValueError, match=r"'solo' scenario plays one bot"):
        dataclasses.replace(task, scenario="solo")


def test_wheel_legged_bots_share_one_world():
    task = dataclasses.replace(
        SUITE["bbbench/MultiBalance-v1"],
        id="bbbench/LeggedCrossing-v0",
        robot="wheel-legged",
        group=Group(n_bots=3),
        random_return=None,
    )
    env = MultiBalanceEnv(task, action_mode="continuous")
    parallel_api_test(env, num_cycles=50)
    observations, _ = env.reset(seed=1)
    # The robot's own 17 values (asked of the robot), then 3 neighbours of 4 values.
    assert env.observation_space("bot_0").shape == (17 + 4 * 3,)
    legged = bbbench.make("bbbench/LeggedFlatBalance-v0").unwrapped
    first = env.scene.bots[0].read()
    alone = legged.scene.robot.values(
        (first.pitch, first.pitch_rate, first.wheel_speed), 0.0, env.scene.live_targets(0)[0], first
    )
    np.testing.assert_array_equal(observations["bot_0"][:17], np.float32(alone))
    assert len({bot.body for bot in env.scene.bots}) == 3
    for _ in range(20):
        env.step({agent: np.zeros(6, dtype=np.float32) for agent in env.agents})
    assert env.agents  # they stand, legs at rest and wheels still


def test_the_guides_scenario_adds_a_body_observation_and_metric(ball_task):
    env = MultiBalanceEnv(ball_task)
    observations, infos = env.reset(seed=4)
    crossing = MultiBalanceEnv("bbbench/MultiBalance-v1")
    plain, _ = crossing.reset(seed=4)
    client = env.scene.world.client
    assert client.getNumBodies() == crossing.scene.world.client.getNumBodies() + 1
    assert env.observation_space("bot_0").shape == (19,)
    for agent in env.agents:  # the robot's and neighbours' values as Crossing's, then the ball
        np.testing.assert_array_equal(observations[agent][:17], plain[agent])
        right, ahead = observations[agent][17:]
        assert math.hypot(right, ahead) == pytest.approx(infos[agent]["ball_distance"], abs=0.2)
    assert env.metrics == ("velocity_error", "ball_distance")
    result = MultiEpisode(env, lambda batch, rngs: [4] * len(batch), 4).play()
    assert list(result.metrics) == ["velocity_error", "ball_distance"]
    assert 0.0 < result.metrics["ball_distance"] < 5.0
    assert list(result.record())[5:7] == ["velocity_error", "ball_distance"]


def test_the_guides_scenario_plays_an_episode_the_same_after_any_other(ball_task):
    def episode(env, seed):
        observations, _ = env.reset(seed=seed)
        rows = [observations["bot_0"].copy()]
        for _ in range(60):
            observations, *_ = env.step(dict.fromkeys(env.agents, 6))
            if "bot_0" in observations:
                rows.append(observations["bot_0"].copy())
        return np.array(rows)

    fresh = episode(MultiBalanceEnv(ball_task), 7)
    reused = MultiBalanceEnv(ball_task)
    episode(reused, 8)
    np.testing.assert_array_equal(episode(reused, 7), fresh)


def test_a_pickled_copy_of_the_guides_scenario_builds_its_own_world(ball_task):
    env = MultiBalanceEnv(ball_task)
    first, _ = env.reset(seed=3)
    copy = cloudpickle.loads(cloudpickle.dumps(env))
    again, _ = copy.reset(seed=3)
    assert copy.scene.world.client_id != env.scene.world.client_id
    for agent, observation in first.items():
        np.testing.assert_array_equal(again[agent], observation)


def test_every_file_the_guide_names_exists():
    text = (REPO / "docs/architecture.md").read_text()
    guide = text[text.index("- **A scenario.**") : text.index("## One episode, written once")]
    named = set(re.findall(r"`((?:bbbench|tests|docs)/[\w/.<>-]+)`", guide))
    assert len(named) >= 5
    for path in named:
        if "<" not in path:  # `bbbench/tasks/scenarios/<name>.py` is the new file
            assert (REPO / path).exists(), path


def test_the_scenario_base_lists_what_a_scenario_owns():
    for method in ("build", "move_clear", "starts", "place", "observation_space", "leave"):
        assert method in Scenario.__dict__
    assert Scenario.metrics == ("velocity_error",)


def test_every_task_of_the_suite_is_on_a_declared_track_and_an_undeclared_one_is_refused():
    for task in SUITE.values():
        assert track_of(task).holds(task)
    legged_group = dataclasses.replace(
        SUITE["bbbench/MultiBalance-v1"], id="bbbench/LeggedCrossing-v0", robot="wheel-legged"
    )
    with pytest.raises(ValueError, match=r"no track ranks the wheel-legged robot's multi-bot"):
        track_of(legged_group)


@pytest.mark.parametrize("task_id", bbbench.list_tasks(latest=True))
def test_a_scenarios_layout_names_every_value_a_bot_observes(task_id):
    task = SUITE[task_id]
    scenario = task.scenario_class(task)
    n = task.group.n_bots if task.multi_agent else 1
    layouts = [scenario.bot_layout(i) for i in range(n)]  # each its robot's on a mixed team
    for layout in layouts:
        names = [field.name for field in layout]
        assert len(set(names)) == len(names)
        assert all(field.low < field.high and field.meaning for field in layout)
    if task.multi_agent:
        env = bbbench.make_parallel(task_id)
        observations, _ = env.reset(seed=0)
        widths = [len(observations[agent]) for agent in env.possible_agents]
    else:
        env = bbbench.make(task_id)
        widths = [len(env.reset(seed=0)[0])]
    env.close()
    assert widths == [len(layout) for layout in layouts]


def test_a_scenario_heading_for_what_no_guide_follows_is_refused_when_registered():
    from bbbench.policies.controllers.steer import GUIDES
    from bbbench.tasks.scenario import HEADINGS, register_scenario

    assert tuple(GUIDES) == HEADINGS

    class Wander(Solo):
        name = "wander"
        heads_for = "the nearest tree"

    with pytest.raises(ValueError, match="heads_for is 'the nearest tree'; it is one of"):
        register_scenario(Wander)
    assert "wander" not in SCENARIOS


def ledger(base: type[Scenario]) -> type[Scenario]:
    """`base`, noting the order the env calls its rules in."""

    class Ledger(base):
        name = f"{base.name}-ledger"

        def __init__(self, task) -> None:
            super().__init__(task)
            self.calls: list[tuple[str, int]] = []

        def observe(self, scene, states, commands, targets, step):
            self.calls.append(("observe", step))
            return super().observe(scene, states, commands, targets, step)

        def outcome(self, agents, states, targets, seed):
            self.calls.append(("outcome", seed))
            return super().outcome(agents, states, targets, seed)

    return Ledger


@pytest.mark.parametrize(
    ("scenario", "row"), [(ledger(Solo), "FlatBalance-v1"), (ledger(Crossing), "MultiBalance-v1")]
)
def test_both_envs_follow_one_step_protocol(monkeypatch, scenario, row):
    """After every reset and every step, observe and then outcome, with the episode's
    seed: the order `Scenario.observe_and_score` writes once, in either env."""
    monkeypatch.setitem(SCENARIOS, scenario.name, scenario)
    task = dataclasses.replace(SUITE[f"bbbench/{row}"], scenario=scenario.name)
    if task.multi_agent:
        env = MultiBalanceEnv(task)
        env.reset(seed=11)
        for _ in range(2):
            env.step({agent: 4 for agent in env.agents})
    else:
        env = BalanceEnv(task)
        env.reset(seed=11)
        for _ in range(2):
            env.step(4)
    assert env.scene.scenario.calls == [
        ("observe", 0), ("outcome", 11), ("observe", 1), ("outcome", 11),
        ("observe", 2), ("outcome", 11),
    ]  # fmt: skip
    env.close()


def test_a_scenario_that_overrides_the_step_protocol_is_refused_when_registered():
    from bbbench.tasks.scenario import register_scenario

    class Backwards(Solo):
        name = "backwards"

        def observe_and_score(self, scene, agents, states, commands, targets, seed):
            outcome = self.outcome(agents, states, targets, seed)
            return self.observe(scene, states, commands, targets, scene.steps), outcome

    with pytest.raises(ValueError, match="'backwards' overrides observe_and_score"):
        register_scenario(Backwards)
    assert "backwards" not in SCENARIOS

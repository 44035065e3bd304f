"""Coupled teams in a column (`bbbench.tasks.scenarios.column`): a beam carried by every
bot (`BeamCarry`) and tethers from each bot to the next (`Convoy`), on tasks made here
from MultiBalance-v1's row (the suite's rows come with their calibration)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

import bbbench
from bbbench.dev.teams import candidate_task
from bbbench.envs.multi import MultiBalanceEnv
from bbbench.evaluation.play import MultiEpisode
from bbbench.policies.controllers.pd import PDController
from bbbench.policies.controllers.team import TeamController
from bbbench.robots.layout import INDEX
from bbbench.tasks.commands import ConstantVelocity
from bbbench.tasks.scenarios import Beam, BeamCarry, Convoy, Tether

GRAVITY = 9.81
TARGET = INDEX["target_velocity"]


def team_task(coupling, n_bots: int = 3, command=None, **changes):
    if command is not None:
        changes["command"] = command
    return candidate_task(coupling, n_bots, task_id="bbbench/TeamTest-v0", **changes)


def field(env, name: str) -> int:
    return [f.name for f in env.scene.scenario.layout].index(name)


PD = PDController()


def pd_actions(env, observations):
    return {agent: PD(observations[agent][:5]) for agent in env.agents}


@pytest.mark.parametrize("coupling", [Beam(), Tether()])
def test_pettingzoo_api_and_seed_tests_pass(coupling):
    parallel_api_test(MultiBalanceEnv(team_task(coupling)), num_cycles=100)


def test_the_beam_rests_on_the_torsos_tops_and_its_weight_is_shared():
    env = MultiBalanceEnv(team_task(Beam(mass=1.5), command=ConstantVelocity(0.0)))
    observations, _ = env.reset(seed=2**31)
    for _ in range(200):
        observations, *_ = env.step(pd_actions(env, observations))
    assert len(env.agents) == 3
    across = [observations[agent][field(env, "hinge_force_across")] for agent in env.agents]
    # The beam presses down on the bots: together they hold its weight.
    assert sum(across) == pytest.approx(-1.5 * GRAVITY, rel=0.05)
    assert all(force < 0 for force in across)
    assert abs(observations["bot_0"][field(env, "beam_pitch")]) < 0.02
    scenario = env.scene.scenario
    (_, _, z), _ = env.scene.world.client.getBasePositionAndOrientation(scenario.beam)
    assert z == pytest.approx(0.5 + 0.02, abs=0.02)  # on the 0.5 m tops


def test_only_the_front_bot_observes_the_team_target_and_end_bots_have_one_neighbour():
    env = MultiBalanceEnv(team_task(Beam(), command=ConstantVelocity(1.5)))
    observations, _ = env.reset(seed=3)
    assert observations["bot_0"][TARGET] == pytest.approx(1.5)
    assert observations["bot_1"][TARGET] == observations["bot_2"][TARGET] == 0.0
    ahead, behind = field(env, "ahead_present"), field(env, "behind_present")
    assert [observations[a][ahead] for a in env.agents] == [0.0, 1.0, 1.0]
    assert [observations[a][behind] for a in env.agents] == [1.0, 1.0, 0.0]
    forward = field(env, "ahead_forward")
    assert observations["bot_1"][forward] == pytest.approx(0.6, abs=1e-3)
    assert env.observation_space("bot_0").shape == (19,)
    assert env.observation_space("bot_0").contains(observations["bot_1"])


@pytest.mark.parametrize("coupling", [Beam(), Tether()])
def test_the_team_earns_one_reward_and_a_fall_of_any_bot_ends_every_agent(coupling):
    env = MultiBalanceEnv(team_task(coupling, command=ConstantVelocity(0.0)))
    env.reset(seed=5)
    rng = np.random.default_rng(0)
    steps = 0
    while env.agents:
        actions = {agent: int(rng.integers(9)) for agent in env.agents}  # random
        _, rewards, terminations, truncations, infos = env.step(actions)
        steps += 1
        assert len(set(rewards.values())) == 1
        assert 0.0 <= rewards["bot_0"] <= 0.1
        terms = infos["bot_0"]["reward_upright"] + infos["bot_0"]["reward_velocity"]
        assert terms == rewards["bot_0"]
    assert steps < 1500
    assert all(terminations.values())  # every agent ends in the same step ...
    assert not any(truncations.values())
    tilts = [bot.read().tilt for bot in env.scene.bots]
    assert max(tilts) > 1.0  # ... at the first bot's fall
    assert env.ended_at == dict.fromkeys(env.possible_agents, steps)


def test_a_tether_pulls_a_follower_that_ignores_it():
    def follower_speed(stiffness: float) -> float:
        tether = Tether(stiffness=stiffness, damping=0.0, breaking_stretch=5.0)
        env = MultiBalanceEnv(team_task(tether, n_bots=2, command=ConstantVelocity(0.8)))
        observations, _ = env.reset(seed=7)
        for _ in range(250):
            observations, *_ = env.step(pd_actions(env, observations))
        return float(env.scene.bots[1].read().forward_velocity)

    assert abs(follower_speed(0.0)) < 0.1  # PD holds the 0 it observes
    assert follower_speed(40.0) > 0.2  # dragged along by the leader


def test_a_tether_stretched_past_its_breaking_stretch_ends_the_team():
    tether = Tether(stiffness=0.0, damping=0.0, breaking_stretch=0.05)
    env = MultiBalanceEnv(team_task(tether, n_bots=2, command=ConstantVelocity(1.0)))
    observations, _ = env.reset(seed=7)
    stretch = field(env, "stretch_behind")
    while env.agents:
        last = observations["bot_0"][stretch]
        observations, _, terminations, _, _ = env.step(pd_actions(env, observations))
    assert all(terminations.values())
    assert observations["bot_0"][stretch] > 0.05 >= last
    assert all(bot.read().tilt < 1.0 for bot in env.scene.bots)  # ended by the break


@pytest.mark.parametrize("coupling", [Beam(), Tether()])
def test_an_episode_plays_the_same_after_any_other(coupling):
    def episode(env, seed):
        observations, _ = env.reset(seed=seed)
        rows = [observations["bot_1"].copy()]
        for _ in range(150):
            observations, *_ = env.step(pd_actions(env, observations))
            if not env.agents:
                break
            rows.append(observations["bot_1"].copy())
        return np.array(rows)

    fresh = episode(MultiBalanceEnv(team_task(coupling)), 11)
    reused = MultiBalanceEnv(team_task(coupling))
    episode(reused, 12)
    np.testing.assert_array_equal(episode(reused, 11), fresh)


def test_what_a_team_task_refuses_says_the_task_and_what_it_takes():
    with pytest.raises(ValueError, match=r"n_bots must be from 2 to 4 for the 'beam-carry'"):
        team_task(Beam(), n_bots=5)
    with pytest.raises(ValueError, match=r"'beam-carry' scenario cannot play the wheel-legged"):
        team_task(Beam(), robot="wheel-legged")
    with pytest.raises(ValueError, match=r"'convoy' scenario needs a Tether coupling"):
        dataclasses.replace(team_task(Tether()), coupling=Beam())
    with pytest.raises(ValueError, match=r"Beam mass must be a number in \[0.1, 10\] kg"):
        Beam(mass=-1.0)
    with pytest.raises(ValueError, match=r"Tether breaking_stretch must be a number"):
        Tether(breaking_stretch=math.nan)


def test_the_layouts_name_every_value_once():
    for scenario in (BeamCarry, Convoy):
        names = [f.name for f in scenario(team_task(scenario.coupling_type())).layout]
        assert len(names) == len(set(names)) == 19


def play_team(env, seed: int, control) -> tuple[int, float]:
    """One episode under `control` (an observation in, an action out, for every bot): its
    length and the team's return (every bot's, as the reward is the team's)."""
    result = MultiEpisode(env, lambda batch, _: [control(row) for row in batch], seed).play()
    return result.length, result.episode_return


@pytest.mark.parametrize("coupling", [Beam(mass=1.0), Tether()])
def test_the_team_controller_beats_bots_that_ignore_each_other(coupling):
    """The coupling matters: followers under PD alone hold the 0 they observe and are
    dragged, or drag, where the team controller's follow the bot ahead and the pull."""
    env = MultiBalanceEnv(team_task(coupling))
    team = TeamController.for_scenario(env.scene.scenario)
    seeds = [2**31 + k for k in range(6)]
    naive = [play_team(env, seed, lambda observation: PD(observation[:5])) for seed in seeds]
    led = [play_team(env, seed, team) for seed in seeds]
    assert sum(length == 1500 for length, _ in naive) <= 4  # naive bots fall ...
    assert all(length == 1500 for length, _ in led)  # ... where the team stays up
    assert sum(r for _, r in led) > 1.5 * sum(r for _, r in naive)


def test_the_team_controller_refuses_a_task_without_a_column():
    crossing = bbbench.spec("bbbench/MultiBalance-v1")
    layout = crossing.robot_model.layout()  # the shared five: no coupling, no neighbours
    with pytest.raises(ValueError, match=r"the team controller plays the column tasks"):
        TeamController(list(layout), "hinge_force_along")


# -- the suite's rows --------------------------------------------------------------------

TEAM_TASKS = ("bbbench/BeamCarry-v0", "bbbench/BeamCarryBumps-v0", "bbbench/Convoy-v0")


def page_observation_rows(task_id: str) -> dict[int, list[str]]:
    """The rows of the observation table on a task's page (docs/environments/, written by
    scripts/site_pages.py), by Num: where the task's tables live."""
    name = task_id.split("/")[1].rsplit("-", 1)[0].lower()
    page = (Path(__file__).parents[1] / "docs" / "environments" / f"{name}.md").read_text()
    lines = page.split("## Observation space")[1].splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("| Num | Observation |"))
    rows = {}
    for line in lines[start + 2 :]:
        if not line.strip().startswith("|"):
            break
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        rows[int(cells[0])] = cells[1:]
    return rows


@pytest.mark.parametrize("task_id", TEAM_TASKS)
def test_the_task_pages_observation_tables_are_the_layouts(task_id):
    task = bbbench.spec(task_id)
    layout = task.scenario_class(task).layout
    rows = page_observation_rows(task_id)
    assert sorted(rows) == list(range(len(layout)))
    for num, (name, low, high, unit, _) in rows.items():
        field_ = layout[num]
        assert (name, unit) == (field_.name, field_.unit)
        assert float(low) == pytest.approx(field_.low, rel=1e-4)
        assert float(high) == pytest.approx(field_.high, rel=1e-4)
    assert [f.name for f in layout[:5]] == list(INDEX)


@pytest.mark.parametrize("task_id", TEAM_TASKS)
def test_each_team_task_is_a_row_with_three_bots_and_the_team_target(task_id):
    env = bbbench.make_parallel(task_id)
    observations, infos = env.reset(seed=2**31)
    assert env.possible_agents == ["bot_0", "bot_1", "bot_2"]
    assert env.observation_space("bot_0").shape == (19,)
    assert bbbench.spec(task_id).command.top_target == 2.0
    assert [observations[a][TARGET] == 0.0 for a in env.agents] == [False, True, True] or (
        observations["bot_0"][TARGET] == 0.0  # a target of exactly 0 is possible
    )
    assert {info["episode_seed"] for info in infos.values()} == {2**31}


@pytest.mark.parametrize("task_id", TEAM_TASKS)
@pytest.mark.parametrize("action_mode", ["discrete", "continuous"])
def test_pettingzoo_api_test_on_the_suite_rows(task_id, action_mode):
    parallel_api_test(bbbench.make_parallel(task_id, action_mode=action_mode), num_cycles=100)


def test_the_payload_loads_the_beam_and_com_offset_is_refused():
    env = bbbench.make_parallel(TEAM_TASKS[0], payload_mass=1.0)
    env.reset(seed=2**31)
    scenario = env.scene.scenario
    client = env.scene.world.client
    assert client.getDynamicsInfo(scenario.beam, -1)[0] == pytest.approx(2.5)
    torso = bbbench.make_parallel(TEAM_TASKS[0])
    torso.reset(seed=2**31)
    bodies = [bot.body for bot in env.scene.bots]
    reference = [bot.body for bot in torso.scene.bots]
    masses = [client.getDynamicsInfo(body, -1)[0] for body in bodies]
    built = [torso.scene.world.client.getDynamicsInfo(body, -1)[0] for body in reference]
    assert masses == built  # the torsos as built
    with pytest.raises(ValueError, match=r"com_offset does not apply to bbbench/BeamCarry-v0: "):
        bbbench.make_parallel(TEAM_TASKS[0], com_offset=0.02)
    bbbench.make_parallel(TEAM_TASKS[2], com_offset=0.02).reset(seed=2**31)  # the convoy takes it


@pytest.mark.parametrize("n_bots", [1, 5, 16])
def test_n_bots_outside_2_to_4_is_refused(n_bots):
    with pytest.raises(ValueError, match=r"n_bots must be"):
        bbbench.make_parallel(TEAM_TASKS[1], n_bots=n_bots)


def test_the_team_builtin_plays_the_team_tasks_only():
    from bbbench.policies import load_policy

    team = load_policy("team")
    assert all(team.mismatch(task_id) is None for task_id in TEAM_TASKS)
    assert "is not a team task" in team.mismatch("bbbench/MultiBalance-v1")
    assert "plays the wheel-legged robot" in team.mismatch("bbbench/LeggedBumps-v0")


def test_rollout_shows_the_team_return_its_error_and_what_ended_it(capsys):
    from bbbench.cli import main

    assert main(["rollout", "--task", TEAM_TASKS[2], "--policy", "pd", "--episodes", "3"]) == 0
    out = capsys.readouterr().out
    assert "error m/s  ended by" in out
    assert "mean return (the team's)" in out
    rows = [line for line in out.splitlines() if line.strip()[:1].isdigit()]
    assert len(rows) == 3
    assert all(row.endswith(("time limit", "fell", "a tether broke")) for row in rows)


def test_the_outcome_names_the_fallen_bots_and_a_broken_tether():
    env = bbbench.make_parallel(TEAM_TASKS[2])
    env.reset(seed=2**31)
    scenario = env.scene.scenario
    agents = list(env.agents)
    states = [bot.read() for bot in env.scene.bots]
    targets = [0.0] * len(agents)
    outcome = scenario.outcome(agents, states, targets, 0)
    assert (outcome.over, outcome.cause, outcome.fell) == (False, "", [False] * 3)
    fallen = [state._replace(tilt=1.2) if i == 1 else state for i, state in enumerate(states)]
    outcome = scenario.outcome(agents, fallen, targets, 0)
    assert (outcome.over, outcome.cause, outcome.fell) == (True, "bot_1 fell", [False, True, False])
    # bot_0 moved 0.5 m ahead of where it starts: its tether stretched past 0.4 m
    front = env.scene.bots[0]
    x, y, _ = states[0].axle
    front.reset(xy=(x, y + 0.5))
    moved = [bot.read() for bot in env.scene.bots]
    commands = [bot.wheel_command for bot in env.scene.bots]
    scenario.observe(env.scene, moved, commands, targets, 0)  # reads the tethers
    assert scenario.tethers[0][1] > 0.4
    fallen = [state._replace(tilt=1.2) if i == 1 else state for i, state in enumerate(moved)]
    outcome = scenario.outcome(agents, fallen, targets, 0)
    assert outcome.cause == "bot_1 fell; a tether broke"
    assert sum(outcome.fell) == 1  # the results count the bots that fell: one


def test_a_team_episode_records_its_cause_and_the_bots_that_fell(tmp_path):
    from bbbench.evaluation import evaluate
    from bbbench.policies import load_policy

    document = evaluate(load_policy("pd"), [TEAM_TASKS[2]], episodes=6, workers=1).document
    episodes = document["tasks"][0]["episodes"]
    causes = {episode["cause"] for episode in episodes}
    assert causes <= {"time limit", "a tether broke"} | {
        c for c in causes if c.endswith(("fell", "fell; a tether broke"))
    }
    for episode in episodes:
        named = episode["cause"].split(" fell")[0].split(", ") if "fell" in episode["cause"] else []
        assert episode["falls"] == len(named)  # the bots that fell, not the team's size
        assert episode["success"] is (episode["cause"] == "time limit")
    assert any(episode["cause"] != "time limit" for episode in episodes)


def test_a_rendered_convoy_shows_its_tethers_and_plays_as_an_unrendered_one():
    def play(render_mode):
        env = bbbench.make_parallel(TEAM_TASKS[2], render_mode=render_mode)
        team = TeamController.for_scenario(env.scene.scenario)
        observations, _ = env.reset(seed=2**31)
        rows = []
        for step in range(120):
            observations, *_ = env.step({a: team(observations[a]) for a in env.agents})
            if render_mode and step % 40 == 0:
                assert env.render().shape == (360, 480, 3)
            rows.append(np.stack(list(observations.values())))
        return np.stack(rows), env

    plain, _ = play(None)
    drawn, env = play("rgb_array")
    np.testing.assert_array_equal(plain, drawn)
    env.render()
    scenario, client = env.scene.scenario, env.scene.world.client
    centres = [np.array(client.getBasePositionAndOrientation(b.body)[0]) for b in env.scene.bots]
    assert len(scenario.beads) == 2
    for j, beads in enumerate(scenario.beads):  # each tether's beads on the line between
        for body in beads:
            point = np.array(client.getBasePositionAndOrientation(body)[0])
            a, b = centres[j], centres[j + 1]
            along = np.dot(point - a, b - a) / np.dot(b - a, b - a)
            assert 0 < along < 1
            np.testing.assert_allclose(point, a + along * (b - a), atol=1e-9)

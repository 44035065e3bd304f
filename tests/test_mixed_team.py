"""A mixed team (issue 67): wheel-legged robots and two-wheel bots carrying one beam
(`bbbench.tasks.scenarios.mixed_team`), each in its own robot's spaces."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from gymnasium import spaces
from pettingzoo.test import parallel_api_test

import bbbench
from bbbench.evaluation import evaluate
from bbbench.evaluation.play import MultiEpisode
from bbbench.evaluation.results import dumps
from bbbench.policies import load_policy
from bbbench.policies.errors import PolicyError
from bbbench.policies.policy import RandomActor, TeamActor
from bbbench.robots.layout import INDEX
from conftest import follows_results_schema

MIXED = "bbbench/MixedBeamCarry-v0"
HILLS = "bbbench/MixedBeamCarryBumps-v0"


@pytest.mark.parametrize("task_id", [MIXED, HILLS])
def test_pettingzoo_api_and_seed_tests_pass(task_id):
    parallel_api_test(bbbench.make_parallel(task_id), num_cycles=100)


@pytest.mark.parametrize(
    ("n_bots", "robots"),
    [
        (2, ["wheel-legged", "two-wheel"]),
        (3, ["wheel-legged", "two-wheel", "wheel-legged"]),
        (4, ["wheel-legged", "two-wheel", "wheel-legged", "two-wheel"]),
    ],
)
def test_each_bot_plays_its_robot_in_its_robots_spaces(n_bots, robots):
    env = bbbench.make_parallel(MIXED, n_bots=n_bots)
    assert env.action_mode == "continuous"  # the only mode both robots take
    assert [model.name for model in env.task.bot_robots] == robots
    widths = {"two-wheel": (19, 1), "wheel-legged": (31, 6)}
    for agent, robot in zip(env.possible_agents, robots, strict=True):
        observation_width, action_width = widths[robot]
        assert env.observation_space(agent).shape == (observation_width,)
        assert env.action_space(agent) == spaces.Box(-1.0, 1.0, (action_width,), np.float32)
    # One space object per robot, shared by its bots.
    assert env.action_space("bot_0") is env.action_space(env.possible_agents[2 % n_bots])
    observations, _ = env.reset(seed=7)
    for agent, observation in observations.items():
        assert env.observation_space(agent).contains(observation)
    bodies = {type(bot).__name__ for bot in env.scene.bots}
    assert bodies == {"BalanceBot", "WheelLeggedBot"}
    assert env.task.robot_groups == {
        "wheel-legged": tuple(range(0, n_bots, 2)),
        "two-wheel": tuple(range(1, n_bots, 2)),
    }


def test_only_the_front_bot_observes_the_target_and_the_bots_hold_the_beam_up():
    env = bbbench.make_parallel(MIXED)
    observations, _ = env.reset(seed=2**31 + 3)
    target = env.scene.episode.targets[0, 0]
    assert observations["bot_0"][INDEX["target_velocity"]] == pytest.approx(target)
    assert observations["bot_1"][INDEX["target_velocity"]] == 0.0
    act = load_policy("mixed-team").actor(MIXED)
    for _ in range(200):
        rows = [observations[agent] for agent in env.agents]
        actions = act.team(rows, [env.agent_index[agent] for agent in env.agents])
        observations, *_ = env.step(dict(zip(env.agents, actions, strict=True)))
    assert len(env.agents) == 3
    scenario = env.scene.scenario
    across = [
        observations[agent][[f.name for f in scenario.bot_layout(i)].index("hinge_force_across")]
        for i, agent in enumerate(env.possible_agents)
    ]
    # Together the hinges hold the beam's weight; the front robot, whose legs stand, carries
    # part of it on its wheels.
    assert sum(across) == pytest.approx(-1.5 * 9.81, rel=0.1)
    assert across[0] < 0


def test_an_episode_is_the_same_bits_in_another_process():
    script = textwrap.dedent(
        f"""
        import hashlib, numpy as np, bbbench
        from bbbench.evaluation.play import MultiEpisode
        from bbbench.policies import load_policy
        env = bbbench.make_parallel("{HILLS}")
        rows = []
        for step in MultiEpisode(env, load_policy("mixed-team").actor("{HILLS}"), 5):
            rows += [step.observations[a] for a in sorted(step.observations)]
            if step.step == 300:
                break
        print("digest", hashlib.sha256(np.concatenate(rows).tobytes()).hexdigest())
        """
    )
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    ).stdout
    (theirs,) = [line.split()[1] for line in out.splitlines() if line.startswith("digest ")]
    env = bbbench.make_parallel(HILLS)
    rows = []
    for step in MultiEpisode(env, load_policy("mixed-team").actor(HILLS), 5):
        rows += [step.observations[a] for a in sorted(step.observations)]
        if step.step == 300:
            break
    assert hashlib.sha256(np.concatenate(rows).tobytes()).hexdigest() == theirs


def test_the_mixed_team_controller_beats_each_robot_on_its_own():
    """Naive per-bot control (each robot's own controller on the 0 a follower observes)
    drags the team or falls; the team law on both robots stays up and tracks."""
    env = bbbench.make_parallel(MIXED)
    seeds = bbbench.spec(MIXED).validation_seeds[:6]
    played = {
        name: [MultiEpisode(env, load_policy(name).actor(MIXED), s).play() for s in seeds]
        for name in ("per-bot", "mixed-team")
    }
    assert all(episode.length == 1500 for episode in played["mixed-team"])
    team = sum(episode.episode_return for episode in played["mixed-team"])
    assert team > 1.5 * sum(episode.episode_return for episode in played["per-bot"])


def test_a_team_actor_acts_each_robots_bots_as_one_batch():
    calls = []

    def recorder(name):
        def act(batch, rngs):
            calls.append((name, batch.shape))
            return [f"{name}:{int(row[0])}" for row in batch]

        return act

    actor = TeamActor({"a": recorder("a"), "b": recorder("b")}, ("a", "b"))
    rows = [np.full(2, 0.0), np.full(5, 1.0), np.full(2, 2.0), np.full(5, 3.0), np.full(2, 4.0)]
    assert actor.team(rows, [0, 1, 2, 3, 4]) == ["a:0", "b:1", "a:2", "b:3", "a:4"]
    assert calls == [("a", (3, 2)), ("b", (2, 5))]
    calls.clear()
    assert actor.team(rows[1:2] + rows[4:], [1, 4]) == ["b:1", "a:4"]  # bots 1 and 4 live
    with pytest.raises(TypeError, match=r"acts through team\(rows, bots, rngs\)"):
        actor(np.zeros((1, 2)))
    random = load_policy("random", action_mode="continuous").actor(MIXED)
    assert isinstance(random, TeamActor)
    assert all(isinstance(part, RandomActor) for part in random.actors.values())


def test_what_a_mixed_team_refuses_says_what_it_takes():
    task = bbbench.spec(MIXED)
    with pytest.raises(ValueError, match=r"action_mode must be one of \('continuous',\)"):
        bbbench.make_parallel(MIXED, action_mode="discrete")
    with pytest.raises(ValueError, match=r"a mixed team's robots are two or more of"):
        dataclasses.replace(task, robots=("two-wheel", "wheel-legged"))  # `robot` is first
    with pytest.raises(ValueError, match=r"a mixed team's robots are two or more of"):
        dataclasses.replace(task, robots=("wheel-legged", "a-tank"))
    with pytest.raises(ValueError, match=r"'mixed-beam-carry' scenario cannot play"):
        dataclasses.replace(task, robots=("wheel-legged", "two-wheel-steer"))
    with pytest.raises(ValueError, match=r"'beam-carry' scenario plays one robot"):
        dataclasses.replace(task, scenario="beam-carry")
    with pytest.raises(ValueError, match=r"n_bots must be from 2 to 4"):
        bbbench.make_parallel(MIXED, n_bots=5)
    # A policy of one robot's bots cannot play the team: one line, what it plays.
    for name in ("pd", "team", "legged"):
        assert "plays a mixed team of wheel-legged and two-wheel" in (
            load_policy(name).mismatch(MIXED)
        )
    pd = load_policy("pd")
    with pytest.raises(PolicyError, match=r"cannot play: bbbench/MixedBeamCarry-v0 plays a mixed"):
        evaluate(pd, [MIXED], episodes=1)
    refused = load_policy("mixed-team").mismatch("bbbench/BeamCarry-v0")
    assert "is not a mixed team's task" in refused


def test_adding_the_mixed_team_left_every_published_task_as_it_was():
    """`robots` is an option added later: at its default it is not hashed."""
    beam = bbbench.spec("bbbench/BeamCarry-v0")
    assert dataclasses.replace(beam, robots=()).spec_hash == beam.spec_hash
    assert bbbench.spec(MIXED).spec_hash != beam.spec_hash


# -- a mixed team's policy file: an ONNX policy per robot group ----------------------------


class _Linear:
    """A torch actor of one robot's bots: a fixed linear map, squashed to [-1, 1]."""

    def __new__(cls, width: int, actions: int, seed: int):
        import torch  # lazy: torch, for the tests that export

        torch.manual_seed(seed)
        return torch.nn.Sequential(torch.nn.Linear(width, actions), torch.nn.Tanh())


def _team_file(tmp_path, groups=("wheel-legged", "two-wheel")):
    from bbbench.policies.onnx.export import onnx_bytes
    from bbbench.policies.onnx.team import write_team

    widths = {"wheel-legged": (31, 6), "two-wheel": (19, 1)}
    models = {
        group: onnx_bytes(_Linear(*widths[group], seed), MIXED, algorithm="IPPO", group=group)
        for seed, group in enumerate(groups)
    }
    path = tmp_path / "team.zip"
    write_team(path, models)
    return path, models


def test_a_team_file_plays_each_group_with_its_own_model(tmp_path):
    from bbbench.policies.onnx.policy import OnnxPolicy
    from bbbench.policies.onnx.reader import parse_onnx

    path, models = _team_file(tmp_path)
    team = load_policy(path)
    assert type(team).__name__ == "TeamFilePolicy"
    assert team.mismatch(MIXED) is None
    assert team.mismatch(HILLS) is None
    assert "is not a mixed team's task" in team.mismatch("bbbench/BeamCarry-v0")
    # Each bot acts as its group's model alone would.
    env = bbbench.make_parallel(MIXED)
    observations, _ = env.reset(seed=2**31)
    rows = [observations[agent] for agent in env.agents]
    acted = team.actor(MIXED).team(rows, [0, 1, 2])
    for bot, action in enumerate(acted):
        group = env.task.bot_robots[bot].name
        alone = OnnxPolicy(parse_onnx(models[group], group, group)).actor(MIXED)
        np.testing.assert_array_equal(action, alone(rows[bot][None])[0])
    # Scored as any policy file; the same bytes give the same results.
    document = evaluate(team, [MIXED], episodes=2).document
    again = evaluate(load_policy(path), [MIXED], episodes=2).document["tasks"][0]["episodes"]
    assert document["tasks"][0]["episodes"] == again
    # Its results document follows the published schema, each group's model named.
    follows_results_schema(json.loads(dumps(document)))
    assert document["policy"]["groups"] == {
        group: hashlib.sha256(model).hexdigest() for group, model in models.items()
    }
    write_again = tmp_path / "again"
    write_again.mkdir()
    assert _team_file(write_again)[0].read_bytes() == path.read_bytes()


def test_a_team_file_that_lacks_a_group_is_one_line_and_exit_2(tmp_path, capsys):
    from bbbench.cli import main

    path, _ = _team_file(tmp_path, groups=("wheel-legged",))
    team = load_policy(path)
    reason = team.mismatch(MIXED)
    assert "lacks a policy for two-wheel" in reason
    assert "\n" not in reason
    assert main(["eval", str(path), "--task", MIXED, "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert "lacks a policy for two-wheel" in err
    assert "Traceback" not in err


@pytest.mark.parametrize(
    ("members", "expected"),
    [
        ({"team.json": b"{not json"}, "team.json is not JSON"),
        ({"team.json": b'{"format": "other/1", "groups": {}}'}, 'must be {"format"'),
        (
            {"team.json": b'{"format": "bbbench-team/1", "groups": {"a-tank": "a.onnx"}}'},
            "a group is a robot",
        ),
        (
            {"team.json": b'{"format": "bbbench-team/1", "groups": {"two-wheel": "x.onnx"}}'},
            "the zip holds no such member",
        ),
        ({"team.json": b"{}", "notes.txt": b"hello"}, "at most 3 .onnx models"),
        (
            {
                "team.json": b'{"format": "bbbench-team/1", "groups": {"two-wheel": "t.onnx"}}',
                "t.onnx": b"not a model",
            },
            "t.onnx: not an ONNX model",
        ),
    ],
)
def test_a_broken_team_file_is_refused_in_one_line(tmp_path, members, expected):
    import zipfile

    path = tmp_path / "team.zip"
    with zipfile.ZipFile(path, "w") as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    with pytest.raises(PolicyError) as refused:
        load_policy(path)
    assert expected in str(refused.value)
    assert "\n" not in str(refused.value)


def test_the_board_reads_a_team_file_as_a_runs_policy(tmp_path):
    import json
    import shutil

    from bbbench.leaderboard.submissions import read_method

    submissions = Path(__file__).parents[1] / "leaderboards" / "submissions"
    folder = tmp_path / "submissions" / "ippo-team"
    run = folder / "runs" / "s0"
    run.mkdir(parents=True)
    method = submissions / "ippo-rendezvous-v0-3m"
    metadata = json.loads((method / "submission.json").read_text())
    recipe = {"world_steps": 1000, "tasks": [MIXED], "file": "a BenchMARL experiment"}
    metadata.update(name="IPPO team", tracks=["mixed-team"], action_mode="continuous")
    metadata["recipe"] = recipe
    (folder / "submission.json").write_text(json.dumps(metadata))
    run_record = json.loads((method / "runs" / "s0" / "run.json").read_text())
    run_record.update(training_seed=0, recipe=recipe)
    (run / "run.json").write_text(json.dumps(run_record))
    shutil.copyfile(_team_file(tmp_path)[0], run / "policy.zip")
    (read,) = read_method(folder).runs
    policy = read.load_policy()
    assert type(policy).__name__ == "TeamFilePolicy"
    assert policy.mismatch(MIXED) is None
    assert set(policy.record()["groups"]) == {"wheel-legged", "two-wheel"}

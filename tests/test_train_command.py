"""`bbbench train`: recipes, seeded and repeatable, its outputs, and its refusals."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from stable_baselines3 import PPO

import bbbench
from bbbench import training
from bbbench.cli import main
from bbbench.evaluation.episodes import LockstepPlayer
from bbbench.policies import load_policy
from bbbench.training.algorithms import TRAINABLE
from bbbench.training.recipe_files import recipe_file
from bbbench.training.sb3.recipes import (
    parse_normalize,
    parse_policy_kwargs,
    recipe,
    recipes,
)
from conftest import load_script

FLAT = "bbbench/FlatBalance-v1"  # the tasks the recipes train: the latest versions
MULTI = "bbbench/MultiBalance-v1"
TINY = ["--steps", "1024", "--eval-episodes", "2"]


def train_exit(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(["train", *argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.mark.slow
def test_the_same_command_twice_writes_the_same_zip_and_every_output(tmp_path, capsys):
    for name in ("first", "second"):
        (tmp_path / name).mkdir()
        out = tmp_path / name / "policy.zip"
        code, stdout, err = train_exit(capsys, FLAT, "--algo", "ppo", "--out", str(out), *TINY)
        assert code == 0, err
    first, second = tmp_path / "first", tmp_path / "second"
    assert (first / "policy.zip").read_bytes() == (second / "policy.zip").read_bytes()
    assert "FlatBalance-v1" in stdout  # the final eval table
    for name in ("curve.json", "curve.png", "train.json", "results.json"):
        assert (first / name).stat().st_size > 0, name
    curve = json.loads((first / "curve.json").read_text())["points"]
    assert [point["steps"] for point in curve] == sorted(p["steps"] for p in curve)
    assert set(curve[0]) == {"steps", "wall_time_s", "mean", "iqm", "mean_length", "returns"}
    assert len(curve[0]["returns"]) == len(training.evaluation_seeds(FLAT))
    assert curve[0]["mean"] == pytest.approx(sum(curve[0]["returns"]) / len(curve[0]["returns"]))
    record = json.loads((first / "train.json").read_text())
    assert record["trainings_beside"]["samples"] >= 2  # counted at its start and its end
    seeds = record["evaluation_seeds"][FLAT]
    assert seeds == training.evaluation_seeds(FLAT)
    assert not set(seeds) & set(bbbench.spec(FLAT).eval_seeds)
    assert all(seed < 2**31 for seed in seeds)  # training seeds
    drawn = (first / "curve.png").read_bytes()  # not in git: drawn again from the records
    (first / "curve.png").unlink()
    load_script("draw_curves").draw(first)
    assert (first / "curve.png").read_bytes() == drawn
    model = PPO.load(first / "policy.zip", device="cpu")  # stable-baselines3's own load
    assert model.policy.action_space.n == 9
    assert load_policy(first / "policy.zip").mismatch(FLAT) is None  # bbbench's reader


@pytest.mark.slow
def test_a_multi_bot_task_trains_one_shared_policy(tmp_path, capsys):
    out = tmp_path / "policy.zip"
    code, _, err = train_exit(capsys, MULTI, "--algo", "ppo", "--n-envs", "1", "--out", str(out),
                              *TINY)  # fmt: skip
    assert code == 0, err
    policy = load_policy(out)
    assert policy.mismatch(MULTI) is None
    assert policy.mismatch(FLAT) is not None  # it observes the neighbours too


@pytest.mark.slow
def test_a_recipe_with_normalize_keeps_the_statistics_of_the_policy_it_keeps(tmp_path, capsys):
    """The multi-bot recipe trains inside VecNormalize: the statistics of the kept policy
    go where rl-zoo3 puts them, with the same bytes on a second run; `bbbench eval` finds
    them; and the policy they load plays the training seeds exactly as the evaluation
    that chose it did."""
    assert recipe("ppo", MULTI).normalize == {}
    for name in ("first", "second"):
        (tmp_path / name).mkdir()
        out = tmp_path / name / "policy.zip"
        argv = (MULTI, "--algo", "ppo", "--n-envs", "1", "--steps", "2048", "--out", str(out))
        code, stdout, err = train_exit(capsys, *argv, "--eval-episodes", "1")
        assert code == 0, err
        assert f"its VecNormalize statistics {out.parent / 'policy'}" in stdout
    first, second = tmp_path / "first", tmp_path / "second"
    statistics = first / "policy" / "vecnormalize.pkl"
    assert statistics.read_bytes() == (second / "policy" / "vecnormalize.pkl").read_bytes()
    assert (first / "policy.zip").read_bytes() == (second / "policy.zip").read_bytes()
    record = json.loads((first / "train.json").read_text())
    assert record["recipe"]["normalize"] == {}
    assert record["statistics"] == str(statistics)

    policy = load_policy(first / "policy.zip")
    assert "vecnormalize.pkl" in policy.normalization_source
    assert policy.normalization.normalize
    runner = LockstepPlayer(actors={MULTI: policy.actor(MULTI)}, action_mode="discrete",
                           sampled=False)  # fmt: skip
    try:
        played = runner.play(MULTI, training.evaluation_seeds(MULTI))
    finally:
        runner.close()
    mean = float(np.mean([episode.episode_return for episode in played]))
    assert mean == record["best"]["mean"]


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        (True, {}),
        (False, None),
        ("{'norm_obs': True, 'norm_reward': False}", {"norm_obs": True, "norm_reward": False}),
    ],
)
def test_normalize_reads_rl_zoo3_s_forms(value, expected):
    assert parse_normalize(value, "ppo.yml, x") == expected


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        ("yes", "expected true, false or a dict of VecNormalize keywords"),
        ("{'gamma': 0.9}", "normalize sets gamma; it takes norm_obs"),
        ("__import__('os')", "expected true, false or a dict"),
    ],
)
def test_a_bad_normalize_is_refused_saying_what_it_takes(value, expected):
    with pytest.raises(ValueError, match=re.escape(expected)):
        parse_normalize(value, "ppo.yml, x")


def test_a_file_where_the_statistics_go_is_refused_before_training(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("policy").write_text("mine")
    code, _, err = train_exit(capsys, MULTI, "--algo", "ppo", "--out", "policy.zip", *TINY)
    assert code == 2, err
    assert "statistics go to policy/vecnormalize.pkl, but policy is a file" in err
    assert sorted(path.name for path in tmp_path.iterdir()) == ["policy"]
    assert Path("policy").read_text() == "mine"


@pytest.mark.slow
def test_several_tasks_train_one_generalist(tmp_path):
    tasks = [FLAT, "bbbench/Bumps-v2"]
    trained = training.train(
        tasks, "ppo", out=tmp_path / "policy.zip", steps=1024, n_envs=2, final_episodes=2
    )
    assert [block["task"] for block in trained.results["tasks"]] == tasks
    record = json.loads((tmp_path / "train.json").read_text())
    assert record["recipe"]["recipe"] == training.MIX
    assert set(record["evaluation_seeds"]) == set(tasks)


@pytest.mark.slow
def test_sac_trains_in_continuous_mode(tmp_path):
    trained = training.train(
        [FLAT], "sac", out=tmp_path / "policy.zip", steps=300, final_episodes=1
    )
    assert load_policy(trained.out).action_mode == "continuous"


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["bbbench/FlatBalanse-v1", "--algo", "ppo"], "Did you mean 'bbbench/FlatBalance-v1'"),
        (
            ["bbbench/Bumps-v1", "--algo", "ppo"],
            "the recipes train the latest version of each task, here bbbench/Bumps-v2",
        ),
        ([FLAT, "--algo", "pp0"], "unknown algorithm 'pp0'. Did you mean 'ppo'?"),
        ([FLAT, "--algo", "dqn", "--action-mode", "continuous"], "DQN learns discrete actions"),
        ([FLAT, "--algo", "sac", "--action-mode", "discrete"], "SAC learns continuous actions"),
        ([FLAT, "--algo", "ppo", "--steps", "0"], "--steps must be at least 1, got 0"),
        ([FLAT, "--algo", "ppo", "--out", "/nonexistent/policy.zip"], "no directory /nonexistent"),
        ([FLAT, MULTI, "--algo", "ppo"], "a multi-bot task trains on its own"),
    ],
)
def test_bad_requests_are_exit_2_in_one_line_writing_nothing(
    capsys, tmp_path, monkeypatch, argv, expected
):
    monkeypatch.chdir(tmp_path)
    code, _, err = train_exit(capsys, *argv)
    assert code == 2, err
    assert err.startswith("bbbench: error:")
    assert len(err.strip().splitlines()) == 1, err
    assert expected in err
    assert list(tmp_path.iterdir()) == []


def test_every_recipe_reads_as_data():
    for algorithm in TRAINABLE:
        for key in recipes(algorithm):
            plan = recipe(algorithm, key)
            assert plan.n_timesteps > 0
            assert plan.n_envs > 0
    assert (
        parse_policy_kwargs("dict(net_arch=[64, 64], activation_fn=nn.ReLU)")[
            "activation_fn"
        ].__name__
        == "ReLU"
    )
    with pytest.raises(ValueError, match="expected dict"):
        parse_policy_kwargs("__import__('os').system('true')")
    with pytest.raises(ValueError, match="must be a literal"):
        parse_policy_kwargs("dict(net_arch=open('x'))")


@pytest.mark.slow
def test_rl_zoo3_trains_with_the_shipped_recipe_file(tmp_path):
    pytest.importorskip("rl_zoo3", reason="rl-zoo3 is in the test extras")
    conf = recipe_file("ppo")
    argv = [
        sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", FLAT,
        "--gym-packages", "bbbench", "-conf", str(conf), "-n", "2048", "-f",
        str(tmp_path / "logs"), "--seed", "0", "--eval-freq", "-1", "--device", "cpu",
    ]  # fmt: skip
    run = subprocess.run(argv, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    saved = list(Path(tmp_path / "logs").rglob("*.zip"))
    assert saved, run.stdout[-2000:]
    assert load_policy(saved[0]).mismatch(FLAT) is None


@pytest.mark.parametrize("algorithm", TRAINABLE)
def test_every_shipped_recipe_learns_from_the_task_s_own_reward(algorithm):
    """No recipe shapes the reward in training: each trains on the latest version of a
    task, with the env as `gym.make` builds it."""
    table = recipes(algorithm)
    latest = set(bbbench.list_tasks(latest=True))
    for key in table:
        assert key in latest or key == training.MIX
        assert "env_wrapper" not in table[key]
        recipe(algorithm, key)


def test_a_recipe_that_would_wrap_the_env_is_refused(tmp_path, monkeypatch):
    text = (
        "bbbench/FlatBalance-v1:\n  n_timesteps: 1000\n"
        "  env_wrapper:\n    - some.module.AliveBonus:\n        bonus: 0.1\n"
    )
    (tmp_path / "ppo.yml").write_text(text)
    with pytest.raises(ValueError, match="env_wrapper is refused: a recipe learns from the task"):
        recipe("ppo", "bbbench/FlatBalance-v1", tmp_path / "ppo.yml")


@pytest.mark.slow
def test_the_final_table_plays_the_task_s_own_reward(tmp_path):
    trained = training.train(
        [FLAT], "td3", out=tmp_path / "p.zip", steps=600, final_episodes=1, eval_freq=300
    )
    # At most 0.1 a step, never below 0 while up.
    assert 0.0 <= trained.results["tasks"][0]["aggregate"]["mean"] <= 150.0


@pytest.mark.slow
def test_a_trainings_bytes_do_not_depend_on_what_its_process_sampled_before(tmp_path):
    """Envs once shared one observation-space object per process, and a zip pickles the
    space with its random generator: sampling any env's space changed the next zip."""

    def trained(name: str) -> bytes:
        out = tmp_path / name
        training.train([FLAT], "ppo", out=out, steps=300, seed=1, eval_freq=300, final_episodes=1)
        return out.read_bytes()

    first = trained("first.zip")
    space = bbbench.make(FLAT).observation_space
    space.seed(5)
    space.sample()
    assert bbbench.make(FLAT).observation_space is not space
    assert trained("second.zip") == first

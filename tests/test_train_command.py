"""`bbbench train`: recipes, seeded and repeatable, its outputs, and its refusals."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from stable_baselines3 import PPO

import bbbench
from bbbench import training
from bbbench.cli import main
from bbbench.policies import load_policy
from bbbench.training.recipes import (
    ALGORITHMS,
    parse_env_wrapper,
    parse_policy_kwargs,
    recipe,
    recipes,
)
from conftest import FLAT

MULTI = "bbbench/MultiBalance-v0"
TINY = ["--steps", "1024", "--eval-episodes", "2"]


def train_exit(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(["train", *argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_the_same_command_twice_writes_the_same_zip_and_every_output(tmp_path, capsys):
    for name in ("first", "second"):
        (tmp_path / name).mkdir()
        out = tmp_path / name / "policy.zip"
        code, stdout, err = train_exit(capsys, FLAT, "--algo", "ppo", "--out", str(out), *TINY)
        assert code == 0, err
    first, second = tmp_path / "first", tmp_path / "second"
    assert (first / "policy.zip").read_bytes() == (second / "policy.zip").read_bytes()
    assert "FlatBalance-v0" in stdout  # the final eval table
    for name in ("curve.json", "curve.png", "train.json", "results.json"):
        assert (first / name).stat().st_size > 0, name
    curve = json.loads((first / "curve.json").read_text())["points"]
    assert [point["steps"] for point in curve] == sorted(p["steps"] for p in curve)
    assert set(curve[0]) == {"steps", "wall_time_s", "mean", "iqm", "mean_length"}
    record = json.loads((first / "train.json").read_text())
    seeds = record["evaluation_seeds"][FLAT]
    assert seeds == training.evaluation_seeds(FLAT)
    assert not set(seeds) & set(bbbench.spec(FLAT).eval_seeds)
    assert all(seed < 2**31 for seed in seeds)  # training seeds
    model = PPO.load(first / "policy.zip", device="cpu")  # stable-baselines3's own load
    assert model.policy.action_space.n == 9
    assert load_policy(first / "policy.zip").mismatch(FLAT) is None  # bbbench's reader


def test_a_multi_bot_task_trains_one_shared_policy(tmp_path, capsys):
    out = tmp_path / "policy.zip"
    code, _, err = train_exit(capsys, MULTI, "--algo", "ppo", "--n-envs", "1", "--out", str(out),
                              *TINY)  # fmt: skip
    assert code == 0, err
    policy = load_policy(out)
    assert policy.mismatch(MULTI) is None
    assert policy.mismatch(FLAT) is not None  # it observes the neighbours too


def test_several_tasks_train_one_generalist(tmp_path):
    tasks = [FLAT, "bbbench/Bumps-v1"]
    trained = training.train(
        tasks, "ppo", out=tmp_path / "policy.zip", steps=1024, n_envs=2, final_episodes=2
    )
    assert [block["task"] for block in trained.results["tasks"]] == tasks
    record = json.loads((tmp_path / "train.json").read_text())
    assert record["recipe"]["recipe"] == training.MIX
    assert set(record["evaluation_seeds"]) == set(tasks)


def test_sac_trains_in_continuous_mode(tmp_path):
    trained = training.train(
        [FLAT], "sac", out=tmp_path / "policy.zip", steps=300, final_episodes=1
    )
    assert load_policy(trained.out).action_mode == "continuous"


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["bbbench/FlatBalanse-v0", "--algo", "ppo"], "Did you mean 'bbbench/FlatBalance-v0'"),
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
    for algorithm in ALGORITHMS:
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


def test_rl_zoo3_trains_with_the_shipped_recipe_file(tmp_path):
    pytest.importorskip("rl_zoo3", reason="rl-zoo3 is in the test extras")
    conf = training.recipes.recipe_file("ppo")
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


def test_a_terrain_recipe_pays_for_staying_up_and_charges_falls_in_training_only(tmp_path):
    plan = recipe("ppo", "bbbench/Bumps-v1")
    assert plan.wrappers == (
        ("bbbench.training.wrappers.AliveBonus", {"bonus": 0.1}),
        ("bbbench.training.wrappers.FallPenalty", {"penalty": 3.0}),
    )
    env = plan.wrap(bbbench.make("bbbench/Bumps-v1"))
    plain = bbbench.make("bbbench/Bumps-v1")
    env.reset(seed=3)
    plain.reset(seed=3)
    while True:  # the zero action falls
        _, shaped, terminated, truncated, _ = env.step(4)
        _, reward, *_ = plain.step(4)
        if terminated or truncated:
            break
        assert shaped == pytest.approx(reward + 0.1)
    assert terminated
    assert shaped == pytest.approx(reward + 0.1 - 3.0)
    trained = training.train(
        ["bbbench/Bumps-v1"], "ppo", out=tmp_path / "p.zip", steps=1024, n_envs=2,
        final_episodes=1,
    )  # fmt: skip
    assert trained.recipe.wrappers  # and its final table plays the task's own reward
    assert trained.results["tasks"][0]["aggregate"]["mean"] < 20


def test_a_recipe_names_only_bbbench_wrappers():
    with pytest.raises(ValueError, match=r"only bbbench\.training\.wrappers\.\* wrappers"):
        parse_env_wrapper(["os.system"], "ppo.yml, x")


def test_td3_flat_recipe_scales_the_shortfall_in_training_only(tmp_path):
    plan = recipe("td3", FLAT)
    assert plan.wrappers[0] == ("bbbench.training.wrappers.ShortfallScale", {"scale": 10.0})
    env = plan.wrap(bbbench.make(FLAT, action_mode="continuous"))
    plain = bbbench.make(FLAT, action_mode="continuous")
    env.reset(seed=5)
    plain.reset(seed=5)
    while True:  # a constant push falls
        _, shaped, terminated, *_ = env.step([0.3])
        _, reward, *_ = plain.step([0.3])
        if terminated:
            break
        assert shaped == pytest.approx(0.1 - 10.0 * (0.1 - reward))
        assert shaped < reward < 0.1  # a worse step is worse still, the order is kept
    assert shaped == pytest.approx(0.1 - 10.0 * (0.1 - reward) - 3.0)  # and the fall penalty
    trained = training.train(
        [FLAT], "td3", out=tmp_path / "p.zip", steps=600, final_episodes=1, eval_freq=300
    )
    # The final table plays the task's own reward: at most 0.1 a step.
    assert trained.results["tasks"][0]["aggregate"]["mean"] <= 150.0

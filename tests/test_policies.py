"""Reading stable-baselines3 zips without trusting them (bbbench.policies.sb3.reader).

Honest zips from every supported algorithm act exactly as stable-baselines3's
own `predict`; hostile zips run no code and are refused with exit code 2.
"""

from __future__ import annotations

import contextlib
import io
import pickle
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch
from stable_baselines3 import A2C, DQN, PPO, SAC, TD3

import bbbench
from bbbench.evaluation import evaluate
from bbbench.policies import PolicyError, RefusedForSafety, load_policy
from bbbench.policies.sb3.reader import MEMBER_LIMITS
from conftest import Payload, assert_acts_as_predict, eval_exit, pickled, rewrite

FLAT = "bbbench/FlatBalance-v0"
VELOCITY = "bbbench/VelocityTracking-v0"

# (algorithm, action mode, keyword arguments): a few hundred steps of training each.
HONEST = {
    "PPO-discrete": (PPO, "discrete", {"n_steps": 64, "batch_size": 64}),
    "PPO-continuous": (
        PPO,
        "continuous",
        {
            "n_steps": 64,
            "batch_size": 64,
            "policy_kwargs": {"net_arch": [32, 16], "activation_fn": torch.nn.ReLU},
        },
    ),
    "A2C-discrete": (A2C, "discrete", {}),
    "DQN-discrete": (DQN, "discrete", {"learning_starts": 50}),
    "SAC-continuous": (SAC, "continuous", {"learning_starts": 50, "batch_size": 32}),
    "TD3-continuous": (
        TD3,
        "continuous",
        {"learning_starts": 50, "batch_size": 32, "policy_kwargs": {"net_arch": [64, 32]}},
    ),
}


@pytest.fixture(scope="module")
def honest_zips(tmp_path_factory) -> dict[str, tuple[Path, object]]:
    """Each supported algorithm, trained for 200 steps and saved with model.save()."""
    folder = tmp_path_factory.mktemp("honest")
    zips = {}
    for name, (algorithm, action_mode, kwargs) in HONEST.items():
        env = bbbench.make(FLAT, action_mode=action_mode)
        model = algorithm("MlpPolicy", env, seed=0, device="cpu", **kwargs)
        model.learn(200)
        path = folder / f"{name}.zip"
        model.save(path)
        zips[name] = (path, model)
    return zips


# -- honest zips ----------------------------------------------------------------------


@pytest.mark.parametrize("name", list(HONEST))
def test_honest_zip_acts_as_stable_baselines3_predict(honest_zips, name):
    path, model = honest_zips[name]
    policy = load_policy(path)
    assert policy.algorithm == name.split("-")[0]
    assert policy.action_mode == HONEST[name][1]
    assert_acts_as_predict(path, model, steps=300)


@pytest.mark.parametrize("name", list(HONEST))
def test_honest_zip_scores_the_returns_of_stable_baselines3(honest_zips, name):
    path, model = honest_zips[name]
    evaluation = evaluate(load_policy(path), [FLAT], episodes=3, workers=1)
    env = bbbench.make(FLAT, action_mode=HONEST[name][1])
    for episode, seed in zip(
        evaluation.document["tasks"][0]["episodes"], bbbench.spec(FLAT).eval_seeds, strict=False
    ):
        observation, _ = env.reset(seed=seed)
        total, done = 0.0, False
        while not done:
            action, _ = model.predict(observation, deterministic=True)
            observation, reward, terminated, truncated, _ = env.step(action)
            total += reward
            done = terminated or truncated
        assert episode["seed"] == seed
        assert episode["return"] == pytest.approx(total, rel=1e-6, abs=1e-9)


def test_a_multi_bot_policy_is_shared_by_every_bot(tmp_path):
    vec = bbbench.make_vec("bbbench/MultiBalance-v0", n_envs=1, n_bots=2)
    model = PPO("MlpPolicy", vec, n_steps=32, batch_size=32, seed=0, device="cpu").learn(64)
    model.save(tmp_path / "multi.zip")
    policy = load_policy(tmp_path / "multi.zip")
    assert policy.mismatch("bbbench/MultiBalance-v0") is None
    assert policy.mismatch(FLAT) is not None
    env = bbbench.make_parallel("bbbench/MultiBalance-v0")  # 4 bots: the policy is shared
    observations, _ = env.reset(seed=1)
    batch = np.stack([observations[agent] for agent in env.agents])
    expected, _ = model.predict(batch, deterministic=True)
    assert policy.actor("bbbench/MultiBalance-v0")(batch) == list(expected)


# -- hostile zips ---------------------------------------------------------------------


def test_the_payload_is_live(marker):
    """The stand-in payload really runs when unpickled: the tests below could fail."""
    pickle.loads(pickle.dumps(Payload(marker)))
    assert marker.exists()


def test_stable_baselines3_load_runs_a_payload_in_an_ignored_key_bbbench_does_not(
    honest_zips, tmp_path, marker, capsys
):
    def poison(data):
        data["lr_schedule"] = pickled(marker)

    hostile = rewrite(honest_zips["PPO-discrete"][0], tmp_path / "hostile.zip", poison)
    code, _ = eval_exit(capsys, str(hostile))
    assert code == 0  # never decoded: the file is scored, and nothing ran
    assert not marker.exists()
    with contextlib.suppress(Exception):  # what bbbench never does on a submitted file
        PPO.load(hostile, device="cpu")
    assert marker.exists()


@pytest.mark.parametrize(
    ("key", "expected"),
    [
        ("policy_class", "not a plain reference"),  # a key SB3 pickles
        ("gamma", "where plain data is expected"),  # a key SB3 writes as plain JSON
        ("extra", "does not write"),  # a key SB3 never writes
    ],
)
def test_a_pickle_payload_in_data_runs_nothing_and_exits_2(
    honest_zips, tmp_path, marker, capsys, key, expected
):
    def poison(data):
        data[key] = pickled(marker)

    hostile = rewrite(honest_zips["PPO-discrete"][0], tmp_path / "hostile.zip", poison)
    code, err = eval_exit(capsys, str(hostile))
    assert code == 2
    assert "refused for safety" in err
    assert expected in err
    assert len(err.strip().splitlines()) == 1
    assert not marker.exists()


def test_a_pickle_payload_in_policy_pth_runs_nothing_and_exits_2(
    honest_zips, tmp_path, marker, capsys
):
    path, model = honest_zips["PPO-discrete"]
    state = {**model.policy.state_dict(), "payload": Payload(marker)}
    weights = io.BytesIO()
    torch.save(state, weights)
    hostile = rewrite(path, tmp_path / "hostile.zip", members={"policy.pth": weights.getvalue()})
    code, err = eval_exit(capsys, str(hostile))
    assert code == 2
    assert "refused for safety" in err
    assert "weights_only" in err
    assert not marker.exists()


def test_a_zip_bomb_is_refused_before_inflating(honest_zips, tmp_path, capsys):
    # 200 MB of zeros deflate to about 200 kB.
    bomb = bytes(200 * 2**20)
    hostile = rewrite(
        honest_zips["PPO-discrete"][0], tmp_path / "bomb.zip", members={"policy.pth": bomb}
    )
    assert hostile.stat().st_size < 2**20
    code, err = eval_exit(capsys, str(hostile))
    assert code == 2
    assert "zip bomb" in err
    assert "policy.pth" in err


def test_a_member_whose_header_understates_its_size_is_refused(honest_zips, tmp_path):
    """The cap is checked on the header, and inflating stops at the header's size."""
    big = b"{" + b" " * (MEMBER_LIMITS["data"] + 10) + b"}"
    path = rewrite(honest_zips["PPO-discrete"][0], tmp_path / "liar.zip", members={"data": big})
    content = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as archive:
        info = archive.getinfo("data")
    # Patch the claimed size in the local header and the central directory to 10 bytes.
    size = len(big).to_bytes(4, "little")
    assert content.count(size) == 2
    content = content.replace(size, (10).to_bytes(4, "little"))
    path.write_bytes(bytes(content))
    assert info.file_size == len(big)
    with pytest.raises(PolicyError):
        load_policy(path)


def test_unexpected_members_are_refused(honest_zips, tmp_path, marker, capsys):
    payload = pickle.dumps(Payload(marker))
    hostile = rewrite(
        honest_zips["PPO-discrete"][0], tmp_path / "extra.zip", members={"evil.pkl": payload}
    )
    code, err = eval_exit(capsys, str(hostile))
    assert code == 2
    assert "unexpected member" in err
    assert "evil.pkl" in err
    assert not marker.exists()


# -- other bad files -------------------------------------------------------------------


def test_bad_files_are_one_line_errors(honest_zips, tmp_path, capsys):
    honest = honest_zips["PPO-discrete"][0]
    not_zip = tmp_path / "notes.zip"
    not_zip.write_text("hello")
    truncated = tmp_path / "truncated.zip"
    truncated.write_bytes(honest.read_bytes()[: honest.stat().st_size // 2])
    cases = {
        str(tmp_path / "missing.zip"): "no such file",
        str(not_zip): "not a readable zip",
        str(truncated): "truncated",
        "nonsense-policy": "unknown policy 'nonsense-policy'",
    }
    for argument, expected in cases.items():
        code, err = eval_exit(capsys, argument)
        assert code == 2, argument
        assert expected in err
        assert err.startswith("bbbench: error:")
        assert len(err.strip().splitlines()) == 1


def test_a_policy_whose_spaces_fit_no_task_says_what_each_task_wants(tmp_path, capsys):
    import gymnasium as gym

    model = PPO("MlpPolicy", gym.make("CartPole-v1"), n_steps=32, batch_size=32, device="cpu")
    model.save(tmp_path / "cartpole.zip")
    code, err = eval_exit(capsys, str(tmp_path / "cartpole.zip"))
    assert code == 2
    assert "Box(4,) -> Discrete(2)" in err
    assert "bbbench/FlatBalance-v1 plays the two-wheel robot and wants Box(5,)" in err
    assert "bbbench/MultiBalance-v1 plays the two-wheel robot and wants Box(17,)" in err
    assert "bbbench/LeggedBumps-v0 plays the wheel-legged robot and wants Box(17,)" in err


def test_nan_weights_fail_episodes_with_the_reason_and_the_run_goes_on(honest_zips, tmp_path):
    path, model = honest_zips["PPO-discrete"]
    state = model.policy.state_dict()
    state["action_net.bias"][:] = float("nan")
    weights = io.BytesIO()
    torch.save(state, weights)
    nan_zip = rewrite(path, tmp_path / "nan.zip", members={"policy.pth": weights.getvalue()})
    evaluation = evaluate(load_policy(nan_zip), [FLAT], episodes=3, workers=1)
    task = evaluation.document["tasks"][0]
    assert [e["failure"] for e in task["episodes"]] == ["step 0: the policy's output is NaN"] * 3
    assert task["aggregate"]["failures"] == 3
    assert task["aggregate"]["success_rate"] == 0.0


def test_unsupported_policy_kwargs_are_refused_by_name(honest_zips, tmp_path):
    def custom_extractor(data):
        data["policy_kwargs"] = {"features_extractor_class": "MyExtractor"}

    path = rewrite(honest_zips["PPO-discrete"][0], tmp_path / "custom.zip", custom_extractor)
    with pytest.raises(PolicyError, match="features_extractor_class"):
        load_policy(path)


def test_weights_that_do_not_match_the_architecture_are_refused(honest_zips, tmp_path):
    def wider(data):
        data["policy_kwargs"] = {"net_arch": [128, 128]}

    path = rewrite(honest_zips["PPO-discrete"][0], tmp_path / "wider.zip", wider)
    with pytest.raises(PolicyError, match="do not fit"):
        load_policy(path).actor(FLAT)


def test_the_command_refuses_weights_that_do_not_fit_with_one_line_and_exit_2(
    honest_zips, tmp_path, capsys
):
    def wider(data):
        data["policy_kwargs"] = {"net_arch": [128, 128]}

    path = rewrite(honest_zips["PPO-discrete"][0], tmp_path / "wider.zip", wider)
    code, err = eval_exit(capsys, str(path), "--task", FLAT)
    assert code == 2
    assert err.count("\n") == 1
    assert "do not fit" in err


def test_refusals_are_policy_errors():
    assert issubclass(RefusedForSafety, PolicyError)
    assert str(RefusedForSafety("x")).startswith("refused for safety")


def test_each_task_has_a_classical_controller_that_plays_it():
    from bbbench.policies import classical_controller

    for task_id in bbbench.list_tasks():
        name = classical_controller(task_id)
        assert load_policy(name).mismatch(task_id) is None, (task_id, name)
    assert classical_controller("bbbench/MultiBalance-v1") == "pd"
    assert classical_controller("bbbench/BeamCarry-v0") == "team"
    assert classical_controller("bbbench/LeggedBumps-v0") == "legged"
    assert classical_controller("bbbench/Waypoints-v0") == "steer"
    assert classical_controller("bbbench/Swap-v0") == "steer-avoid"
    assert classical_controller("bbbench/ConvoyTurns-v0") == "team"
    assert classical_controller("bbbench/MixedBeamCarry-v0") == "mixed-team"
    with pytest.raises(ValueError, match="unknown task 'bbbench/Nope-v0'"):
        classical_controller("bbbench/Nope-v0")

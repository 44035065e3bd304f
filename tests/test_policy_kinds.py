"""The policies people bring: VecNormalize statistics, gSDE, sb3-contrib, other dtypes.

Each is scored as its own library would act, or refused in one line that says
what to do; never scored wrong without a word.
"""

from __future__ import annotations

import base64
import contextlib
import hashlib
import io
import json
import pickle
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
from sb3_contrib import ARS, QRDQN, TQC, TRPO, MaskablePPO, RecurrentPPO
from stable_baselines3 import PPO, SAC
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

import bbbench
from bbbench.cli import main
from bbbench.evaluation import evaluate
from bbbench.policies import PolicyError, load_policy
from bbbench.policies.sb3.vecnormalize import read_statistics
from conftest import (
    FLAT,
    Payload,
    assert_acts_as_predict,
    eval_exit,
    follows_results_schema,
    rewrite,
)

VELOCITY = "bbbench/VelocityTracking-v0"


def trained(algorithm, action_mode: str, path: Path, policy="MlpPolicy", steps=128, **kwargs):
    env = bbbench.make(FLAT, action_mode=action_mode)
    model = algorithm(policy, env, seed=0, device="cpu", **kwargs).learn(steps)
    model.save(path)
    return model


# -- VecNormalize ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def normalized_run(tmp_path_factory) -> tuple[Path, Path]:
    """A PPO policy trained inside VecNormalize, saved as rl-zoo3 saves a run:
    `<run>/<env>.zip` and `<run>/<env>/vecnormalize.pkl`."""
    run = tmp_path_factory.mktemp("ppo") / "bbbench-FlatBalance-v0_1"
    (run / "bbbench-FlatBalance-v0").mkdir(parents=True)
    venv = VecNormalize(DummyVecEnv([lambda: bbbench.make(FLAT)]), gamma=0.99)
    model = PPO("MlpPolicy", venv, n_steps=128, batch_size=64, seed=0, device="cpu").learn(512)
    model.save(run / "bbbench-FlatBalance-v0.zip")
    venv.save(run / "bbbench-FlatBalance-v0" / "vecnormalize.pkl")
    return run / "bbbench-FlatBalance-v0.zip", run / "bbbench-FlatBalance-v0" / "vecnormalize.pkl"


def test_a_vecnormalize_policy_without_its_statistics_is_refused_saying_what_to_pass(
    normalized_run, tmp_path, capsys
):
    alone = tmp_path / "policy.zip"
    shutil.copy(normalized_run[0], alone)
    code, err = eval_exit(capsys, str(alone))
    assert code == 2
    assert "VecNormalize" in err
    assert "--vecnormalize PATH" in err
    assert "refused for safety" not in err
    assert len(err.strip().splitlines()) == 1


def test_vecnormalize_returns_equal_stable_baselines3s_own_evaluation(normalized_run):
    zip_path, statistics = normalized_run
    evaluation = evaluate(load_policy(zip_path, vecnormalize=statistics), [FLAT], episodes=4)
    model = PPO.load(zip_path, device="cpu")  # our own file: SB3's load is fine here
    venv = VecNormalize.load(str(statistics), DummyVecEnv([lambda: bbbench.make(FLAT)]))
    venv.training, venv.norm_reward = False, False
    played = evaluation.document["tasks"][0]["episodes"]
    for episode, seed in zip(played, bbbench.spec(FLAT).eval_seeds, strict=False):
        venv.seed(seed)
        returns, lengths = evaluate_policy(
            model, venv, n_eval_episodes=1, deterministic=True, return_episode_rewards=True
        )
        assert episode["length"] == lengths[0]
        assert episode["return"] == pytest.approx(returns[0], rel=1e-5)  # float32 rewards


def test_statistics_beside_the_zip_as_rl_zoo3_saves_them_are_found_said_and_recorded(
    normalized_run, tmp_path, capsys
):
    zip_path, statistics = normalized_run
    out = tmp_path / "results.json"
    code = main(["eval", str(zip_path), "--task", FLAT, "--episodes", "2", "--json", str(out)])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "found beside the policy" in err
    assert str(statistics) in err
    document = json.loads(out.read_text())
    follows_results_schema(document)
    record = document["policy"]["observation_normalization"]
    assert record["sha256"] == hashlib.sha256(statistics.read_bytes()).hexdigest()
    assert record["file"] == "vecnormalize.pkl"


def test_the_normalization_is_the_one_vecnormalize_applies(normalized_run):
    statistics = normalized_run[1]
    venv = VecNormalize.load(str(statistics), DummyVecEnv([lambda: bbbench.make(FLAT)]))
    venv.training = False
    ours = read_statistics(statistics, (5,))
    raw = np.random.default_rng(0).uniform(-30, 30, size=(16, 5)).astype(np.float32)
    np.testing.assert_array_equal(ours(raw), venv.normalize_obs(raw))


class HostileVecNormalize:
    """Pickles as a VecNormalize whose state holds a payload."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        from stable_baselines3.common.vec_env.vec_normalize import VecNormalize

        return (object.__new__, (VecNormalize,), {"obs_rms": Payload(self.marker)})


@pytest.mark.parametrize(
    "make_payload",
    [
        lambda marker: Payload(marker),  # builtins.open at the top
        lambda marker: HostileVecNormalize(marker),  # nested in an allowed class's state
        lambda marker: {"norm_obs": True, "obs_rms": __import__("os").system},  # a global
    ],
    ids=["open", "nested-open", "os.system"],
)
def test_a_hostile_statistics_file_runs_nothing_and_exits_2(
    normalized_run, tmp_path, marker, capsys, make_payload
):
    hostile = tmp_path / "vecnormalize.pkl"
    hostile.write_bytes(pickle.dumps(make_payload(marker)))
    code, err = eval_exit(capsys, str(normalized_run[0]), "--vecnormalize", str(hostile))
    assert code == 2
    assert "refused for safety" in err
    assert str(hostile) in err
    assert len(err.strip().splitlines()) == 1
    assert not marker.exists()


def test_the_payload_of_the_hostile_statistics_is_live(marker):
    with contextlib.suppress(Exception):  # the payload runs before VecNormalize's state fails
        pickle.loads(pickle.dumps(HostileVecNormalize(marker)))
    assert marker.exists()


def test_statistics_of_another_shape_are_refused(normalized_run, tmp_path):
    venv = VecNormalize(bbbench.make_vec("bbbench/MultiBalance-v0", n_envs=1, n_bots=2))
    other = tmp_path / "other.pkl"
    venv.save(other)
    with pytest.raises(PolicyError, match="shape"):
        load_policy(normalized_run[0], vecnormalize=other)


# -- gSDE -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("algorithm", "kwargs"),
    [
        (PPO, {"n_steps": 64, "batch_size": 64, "use_sde": True}),
        (PPO, {"n_steps": 64, "batch_size": 64, "use_sde": True,
               "policy_kwargs": {"squash_output": True}}),
        (SAC, {"learning_starts": 50, "batch_size": 32, "use_sde": True}),
    ],
    ids=["PPO", "PPO-squashed", "SAC"],
)  # fmt: skip
def test_gsde_policies_act_as_their_deterministic_predict(tmp_path, algorithm, kwargs):
    path = tmp_path / "sde.zip"
    model = trained(algorithm, "continuous", path, **kwargs)
    assert_acts_as_predict(path, model)


def test_gsde_policies_refuse_stochastic_evaluation_in_one_line(tmp_path, capsys):
    path = tmp_path / "sde.zip"
    trained(PPO, "continuous", path, n_steps=64, batch_size=64, use_sde=True)
    code, err = eval_exit(capsys, str(path), "--stochastic")
    assert code == 2
    assert "gSDE" in err
    assert len(err.strip().splitlines()) == 1


# -- sb3-contrib ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("algorithm", "action_mode", "policy", "kwargs"),
    [
        (QRDQN, "discrete", "MlpPolicy", {"learning_starts": 50,
                                          "policy_kwargs": {"n_quantiles": 7}}),
        (TQC, "continuous", "MlpPolicy", {"learning_starts": 50, "batch_size": 32}),
        (TRPO, "discrete", "MlpPolicy", {"n_steps": 64, "batch_size": 64}),
        (TRPO, "continuous", "MlpPolicy", {"n_steps": 64, "batch_size": 64}),
        (ARS, "continuous", "MlpPolicy", {"n_delta": 2}),
        (ARS, "discrete", "LinearPolicy", {"n_delta": 2}),
    ],
    ids=["QR-DQN", "TQC", "TRPO-discrete", "TRPO-continuous", "ARS", "ARS-linear"],
)  # fmt: skip
def test_sb3_contrib_policies_act_as_their_own_predict(
    tmp_path, algorithm, action_mode, policy, kwargs
):
    path = tmp_path / "contrib.zip"
    model = trained(algorithm, action_mode, path, policy=policy, steps=200, **kwargs)
    assert load_policy(path).algorithm == algorithm.__name__.replace("QRDQN", "QR-DQN")
    assert_acts_as_predict(path, model)


@pytest.mark.parametrize(
    ("algorithm", "policy", "name"),
    [(RecurrentPPO, "MlpLstmPolicy", "RecurrentPPO"), (MaskablePPO, "MlpPolicy", "MaskablePPO")],
)
def test_other_algorithms_are_not_supported_never_a_safety_refusal(
    tmp_path, capsys, algorithm, policy, name
):
    path = tmp_path / "other.zip"
    algorithm(policy, bbbench.make(FLAT), n_steps=64, batch_size=64, device="cpu").save(path)
    code, err = eval_exit(capsys, str(path))
    assert code == 2
    assert f"algorithm {name}" in err
    assert "is not supported" in err
    assert "refused for safety" not in err


def test_a_cnn_policy_class_is_not_supported(ppo_zip, tmp_path, capsys):
    from stable_baselines3.common.policies import ActorCriticCnnPolicy

    def cnn(data):  # the reference SB3 writes for a class: read, never unpickled
        reference = base64.b64encode(pickle.dumps(ActorCriticCnnPolicy, protocol=5)).decode()
        data["policy_class"][":serialized:"] = reference

    code, err = eval_exit(capsys, str(rewrite(ppo_zip[0], tmp_path / "cnn.zip", cnn)))
    assert code == 2
    assert "algorithm a CNN policy is not supported" in err


# -- dtypes ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def ppo_zip(tmp_path_factory) -> tuple[Path, PPO]:
    path = tmp_path_factory.mktemp("ppo") / "ppo.zip"
    return path, trained(PPO, "discrete", path, n_steps=64, batch_size=64)


def with_weights(path: Path, target: Path, convert) -> Path:
    state = {
        key: convert(value)
        for key, value in PPO.load(path, device="cpu").policy.state_dict().items()
    }
    weights = io.BytesIO()
    torch.save(state, weights)
    return rewrite(path, target, members={"policy.pth": weights.getvalue()})


def test_float64_weights_are_cast_to_float32_and_act_the_same(ppo_zip, tmp_path):
    path, model = ppo_zip
    wide = with_weights(path, tmp_path / "f64.zip", lambda t: t.double())
    assert_acts_as_predict(wide, model, steps=50)


def test_float16_weights_are_accepted(ppo_zip, tmp_path):
    half = with_weights(ppo_zip[0], tmp_path / "f16.zip", lambda t: t.half())
    evaluation = evaluate(load_policy(half), [FLAT], episodes=1, workers=1)
    assert evaluation.document["tasks"][0]["aggregate"]["episodes"] == 1


@pytest.mark.parametrize(
    ("convert", "named"),
    [
        (lambda t: t.to(torch.complex64), "complex64"),
        (lambda t: (t * 100).to(torch.int32), "int32"),
        (lambda t: t > 0, "bool"),
        (lambda t: torch.quantize_per_tensor(t, 0.01, 0, torch.qint8), "quantized"),
        (lambda t: t.to_sparse(), "sparse"),
        (lambda t: torch.empty(t.shape, device="meta"), "meta"),
    ],
    ids=["complex", "integer", "bool", "quantized", "sparse", "meta"],
)
def test_weights_of_other_kinds_are_refused_with_exit_2(ppo_zip, tmp_path, capsys, convert, named):
    odd = with_weights(ppo_zip[0], tmp_path / "odd.zip", convert)
    code, err = eval_exit(capsys, str(odd))
    assert code == 2
    assert named in err
    assert str(odd) in err
    assert len(err.strip().splitlines()) == 1

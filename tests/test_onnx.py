"""ONNX policies: the interpreter, the contract, bbbench export and its parity with the zips."""

from __future__ import annotations

import json
import pickle
import shutil
from pathlib import Path

import numpy as np
import onnx
import pytest
import torch
from onnx import TensorProto, helper, numpy_helper

from bbbench import evaluation
from bbbench.cli import main
from bbbench.policies import PolicyError, export_onnx, export_zip, load_policy
from bbbench.policies.encoder import neighbour_encoder
from bbbench.policies.mlp import MlpActor
from bbbench.policies.onnx.policy import OnnxPolicy
from conftest import follows_results_schema

ROOT = Path(__file__).resolve().parents[1]
SUBMISSIONS = ROOT / "leaderboards" / "submissions"
FLAT = "bbbench/FlatBalance-v1"
BEAM = "bbbench/BeamCarry-v0"


def submission(slug: str):
    if slug == "reference":  # the shipped policy, a zip
        return load_policy(slug)
    method, _, run = slug.rpartition("-")  # a run's slug: <method>-s<seed>
    folder = SUBMISSIONS / method / "runs" / run
    statistics = folder / "vecnormalize.pkl"
    return load_policy(
        folder / "policy.zip", vecnormalize=statistics if statistics.exists() else None
    )


def episodes(policy, task_id: str, count: int) -> list:
    document = evaluation.evaluate(policy, [task_id], episodes=count, workers=1).document
    return document["tasks"][0]["episodes"]


# -- bbbench export: the zips, bit for bit ---------------------------------------


@pytest.mark.parametrize(
    ("slug", "task_id"),
    [
        ("reference", "bbbench/VelocityTracking-v1"),  # plain PPO, discrete
        ("ppo-multibalance-v1-s0", "bbbench/MultiBalance-v1"),  # VecNormalize, 4 bots
        ("ppo-beamcarry-v0-s0", BEAM),  # VecNormalize, a team
        ("sac-leggedbumps-v0-s0", "bbbench/LeggedBumps-v0"),  # SAC: tanh scaled, Box(6)
        ("ppo-leggedflatbalance-v0-s0", "bbbench/LeggedFlatBalance-v0"),  # PPO on a Box
    ],
)
def test_an_exported_zip_plays_the_zips_episodes_byte_for_byte(tmp_path, slug, task_id):
    zipped = submission(slug)
    path = export_zip(zipped, tmp_path / "policy.onnx", task_id=task_id)
    exported = load_policy(path)
    assert exported.algorithm == zipped.algorithm
    assert exported.spaces_text() == zipped.spaces_text()
    assert episodes(exported, task_id, 2) == episodes(zipped, task_id, 2)


def test_a_plain_mlp_compiles_to_the_zips_own_actor_with_its_greedy_path(tmp_path):
    zipped = load_policy("reference")
    exported = load_policy(export_zip(zipped, tmp_path / "reference.onnx"))
    actor = exported.actor(FLAT)
    assert actor.greedy
    assert not actor.program.prefix
    assert not actor.program.suffix
    mlp, theirs = actor.program.mlp, zipped.actor(FLAT)
    for mine, zips in zip([*mlp.hidden, mlp.head], [*theirs.hidden, theirs.head], strict=True):
        assert all(np.array_equal(a, b) for a, b in zip(mine, zips, strict=True))
    rng = np.random.default_rng(1)
    observations = rng.normal(0.0, 3.0, (2000, 5)).astype(np.float32)
    assert actor(observations) == theirs(observations)


def test_vecnormalize_is_kept_in_float64_inside_the_graph(tmp_path):
    zipped = submission("ppo-multibalance-v1-s0")
    model = onnx.load_from_string(export_zip(zipped, tmp_path / "m.onnx").read_bytes())
    ops = [node.op_type for node in model.graph.node]
    assert ops[:5] == ["Cast", "Sub", "Div", "Clip", "Cast"]
    assert model.graph.node[0].attribute[0].i == TensorProto.DOUBLE
    props = {p.key: p.value for p in model.metadata_props}
    assert props["bbbench.observation"] == "17"
    assert props["bbbench.action_space"] == "Discrete(9)"
    assert props["bbbench.algorithm"] == "PPO"


def test_export_refuses_to_write_what_would_play_otherwise(tmp_path, monkeypatch):
    from bbbench.policies.onnx import export as export_module

    zipped = load_policy("reference")
    real = export_module._Graph.layer

    def off_by_one_ulp(self, x, weights):
        weight, bias = weights
        return real(self, x, (weight, np.nextafter(bias, np.float32(np.inf))))

    monkeypatch.setattr(export_module._Graph, "layer", off_by_one_ulp)
    with pytest.raises(PolicyError, match="computes otherwise than the zip"):
        export_zip(zipped, tmp_path / "bad.onnx")
    assert not (tmp_path / "bad.onnx").exists()


def test_bbbench_export_and_eval_from_the_command_line(tmp_path, capsys):
    out = tmp_path / "reference.onnx"
    assert main(["export", "reference", "--out", str(out), "--training-steps", "400000"]) == 0
    assert "wrote" in capsys.readouterr().out
    document = tmp_path / "results.json"
    argv = ["eval", str(out), "--task", FLAT, "--episodes", "2", "--workers", "1"]
    assert main([*argv, "--json", str(document)]) == 0
    follows_results_schema(json.loads(document.read_text()))
    record = json.loads(document.read_text())["policy"]
    assert record["format"] == "onnx"
    assert record["contract"] == {
        "observation": 5,
        "action_space": "Discrete(9)",
        "from": "metadata",
    }
    assert OnnxPolicy(out).training_steps == 400_000


# -- the contract ----------------------------------------------------------------


def bare_mlp(path: Path, inputs: int = 5, outputs: int = 9, batch="batch") -> Path:
    """A two-layer tanh MLP with no bbbench metadata, as a foreign exporter writes one."""
    rng = np.random.default_rng(3)
    w1 = rng.normal(0, 0.5, (inputs, 16)).astype(np.float32)
    w2 = rng.normal(0, 0.5, (16, outputs)).astype(np.float32)
    nodes = [
        helper.make_node("MatMul", ["obs", "w1"], ["h"]),
        helper.make_node("Add", ["h", "b1"], ["hb"]),
        helper.make_node("Tanh", ["hb"], ["t"]),
        helper.make_node("Gemm", ["t", "w2t", "b2"], ["actions"], transB=1),
    ]
    graph = helper.make_graph(
        nodes,
        "g",
        [helper.make_tensor_value_info("obs", TensorProto.FLOAT, [batch, inputs])],
        [helper.make_tensor_value_info("actions", TensorProto.FLOAT, [batch, outputs])],
        [
            numpy_helper.from_array(w1, "w1"),
            numpy_helper.from_array(np.zeros(16, np.float32) + 0.1, "b1"),
            numpy_helper.from_array(np.ascontiguousarray(w2.T), "w2t"),
            numpy_helper.from_array(np.linspace(-1, 1, outputs).astype(np.float32), "b2"),
        ],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 11)])
    path.write_bytes(model.SerializeToString())
    return path


def test_a_file_without_a_contract_is_refused_naming_both_flags(tmp_path, capsys):
    path = bare_mlp(tmp_path / "isaac.onnx")
    code = main(["eval", str(path), "--task", FLAT, "--episodes", "1"])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1
    assert "--observation N" in err
    assert "--action-space SPACE" in err


def test_the_command_lines_contract_scores_it_and_the_results_say_so(tmp_path, capsys):
    path = bare_mlp(tmp_path / "isaac.onnx")
    document = tmp_path / "r.json"
    argv = ["eval", str(path), "--task", FLAT, "--episodes", "1", "--workers", "1"]
    contract = ["--observation", "5", "--action-space", "Discrete(9)", "--json", str(document)]
    assert main([*argv, *contract]) == 0
    follows_results_schema(json.loads(document.read_text()))
    record = json.loads(document.read_text())["policy"]
    assert record["contract"]["from"] == "command line"
    assert record["algorithm"] == "ONNX policy"


def test_the_matmul_add_pair_is_one_layer_as_gemm_is(tmp_path):
    policy = OnnxPolicy(bare_mlp(tmp_path / "p.onnx"), 5, "Discrete(9)")
    actor = policy.actor(FLAT)
    mlp = actor.program.mlp
    assert len(mlp.hidden) == 1
    assert mlp.activation == "Tanh"
    assert actor.greedy
    rng = np.random.default_rng(0)
    observations = rng.normal(0, 2, (500, 5)).astype(np.float32)
    w1, b1 = mlp.hidden[0]
    w2, b2 = mlp.head
    exact = np.tanh(observations.astype(np.float64) @ w1 + b1) @ w2 + b2
    assert np.abs(actor.program(observations) - exact).max() < 1e-5


@pytest.mark.parametrize(
    ("space", "expected"),
    [
        ("Discrete(9)", "Discrete(9)"),
        ("Box(-1.0, 1.0, (1,), float32)", "Box(-1.0, 1.0, (1,), float32)"),
        ("Box(-1.0, 1.0, (6,), float32)", "Box(-1.0, 1.0, (6,), float32)"),
        ("Box([-1. -1.], [1. 1.], (2,), float32)", "Box(-1.0, 1.0, (2,), float32)"),
        ("Box(-1.0, 1.0, (1,))", "Box(-1.0, 1.0, (1,), float32)"),  # as bbbench's errors print it
        ("Box(-1, 1, (1,))", "Box(-1.0, 1.0, (1,), float32)"),  # as the README writes it
    ],
)
def test_action_spaces_are_read_as_gymnasium_prints_them(space, expected):
    from bbbench.policies.onnx.contract import parse_action_space

    assert str(parse_action_space(space, "--action-space")) == expected


@pytest.mark.parametrize(
    "space", ["Discrete(0)", "Discrete(9", "Box(-1.0, 1.0, (1,), float64)", "MultiDiscrete([3])"]
)
def test_a_wrong_action_space_is_one_line(tmp_path, capsys, space):
    path = bare_mlp(tmp_path / "p.onnx")
    argv = ["eval", str(path), "--task", FLAT, "--observation", "5", "--action-space", space]
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1, err


def test_flags_that_disagree_with_the_files_contract_are_refused(tmp_path, capsys):
    out = tmp_path / "reference.onnx"
    export_zip(load_policy("reference"), out)
    capsys.readouterr()
    code = main(["eval", str(out), "--observation", "16", "--task", FLAT, "--episodes", "1"])
    assert code == 2
    assert "disagrees with the file's" in capsys.readouterr().err


def test_an_onnx_policy_refuses_to_act_stochastically(tmp_path, capsys):
    out = export_zip(load_policy("reference"), tmp_path / "reference.onnx")
    code = main(["eval", str(out), "--stochastic", "--task", FLAT, "--episodes", "1"])
    err = capsys.readouterr().err
    assert code == 2
    assert "drop --stochastic" in err


# -- the neighbour encoder -------------------------------------------------------


def team_observations(count: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    observations = rng.normal(0.0, 1.0, (count, 19)).astype(np.float32)
    for presence in (9, 14):  # each slot's presence bit, and a missing slot all zeros
        present = rng.integers(0, 2, count).astype(np.float32)
        observations[:, presence] = present
        observations[:, presence + 1 : presence + 5] *= present[:, None]
    return observations


@pytest.fixture(scope="module", params=[("mean", False), ("max", False), ("mean", True)])
def encoder_policy(request, tmp_path_factory):
    pool, dynamo = request.param
    torch.manual_seed(0)
    module = neighbour_encoder(9, 2, 5, 9, presence=0, pool=pool)
    path = tmp_path_factory.mktemp("encoder") / "encoder.onnx"
    export_onnx(module, BEAM, path, algorithm="MAPPO", training_steps=10, dynamo=dynamo)
    return module, load_policy(path)


def test_a_neighbour_encoder_runs_as_torch_computes_it(encoder_policy):
    module, policy = encoder_policy
    observations = team_observations(1000)
    with torch.no_grad():
        expected = module(torch.from_numpy(observations)).double().numpy()
    actor = policy.actor(BEAM)
    assert not actor.rows
    assert actor.greedy
    assert np.abs(actor.program(observations) - expected).max() < 1e-5


def test_a_neighbour_encoder_is_invariant_to_its_slots_order_and_batching(encoder_policy):
    _, policy = encoder_policy
    actor = policy.actor(BEAM)
    observations = team_observations(300, seed=1)
    swapped = np.concatenate(
        [observations[:, :9], observations[:, 14:19], observations[:, 9:14]], axis=1
    )
    out = actor.program(observations)
    assert np.array_equal(out, actor.program(swapped))
    apart = np.concatenate([actor.program(row[None]) for row in observations])
    assert np.array_equal(out.view(np.uint32), apart.view(np.uint32))
    assert actor(observations) == pickle.loads(pickle.dumps(actor))(observations)


def test_a_neighbour_encoder_plays_a_team_task(encoder_policy):
    _, policy = encoder_policy
    [episode] = episodes(policy, BEAM, 1)
    assert episode["length"] > 0


def test_sums_over_slots_are_in_slot_order_in_float64():
    from bbbench.policies.onnx.operators import reduce

    x = np.array([[[1e8], [1.0], [-1e8]]], dtype=np.float32)  # float32 sums lose the 1
    params = {"axes": (1,), "keepdims": 0, "noop": 0, "kind": "sum"}
    assert reduce(params, x)[0, 0] == np.float32(1.0)


# -- submissions -----------------------------------------------------------------


def test_the_board_takes_an_onnx_submission(tmp_path):
    from bbbench.leaderboard.submissions import read_method

    folder = tmp_path / "submissions" / "ppo-onnx"
    folder.mkdir(parents=True)
    metadata = json.loads((SUBMISSIONS / "pd" / "submission.json").read_text())
    metadata.update(name="PPO (ONNX)", algorithm="PPO")
    del metadata["builtin"]
    (folder / "submission.json").write_text(json.dumps(metadata))
    export_zip(load_policy("reference"), folder / "policy.onnx")
    (run,) = read_method(folder).runs
    assert run.policy_file == folder / "policy.onnx"
    assert run.load_policy().record()["format"] == "onnx"
    statistics = SUBMISSIONS / "ppo-beamcarry-v0" / "runs" / "s0" / "vecnormalize.pkl"
    shutil.copyfile(statistics, folder / "vecnormalize.pkl")
    with pytest.raises(ValueError, match="only a zip takes statistics"):
        read_method(folder)


def test_every_operator_of_the_set_has_its_kernel_and_its_rule_in_one_entry():
    from bbbench.policies.onnx.interpreter import KERNELS
    from bbbench.policies.onnx.operators import OPERATORS, STRUCTURAL, TABLE

    assert set(TABLE) | STRUCTURAL == OPERATORS
    for name, operator in TABLE.items():
        assert KERNELS[name] is operator.run, name
        assert operator.computes in ("float", "float32", "any"), name
    assert MlpActor  # the compiled chain's class


def test_a_graph_exported_for_one_observation_runs_row_by_row_alike(tmp_path):
    """Isaac Lab's exporter writes its input as (1, n): bbbench calls it once per bot."""
    batched = OnnxPolicy(bare_mlp(tmp_path / "any.onnx"), 5, "Discrete(9)").actor(FLAT)
    single = OnnxPolicy(bare_mlp(tmp_path / "one.onnx", batch=1), 5, "Discrete(9)").actor(FLAT)
    assert single.rows
    assert not batched.rows
    observations = np.random.default_rng(4).normal(0, 2, (64, 5)).astype(np.float32)
    assert single(observations) == batched(observations)


def test_an_onnx_policy_is_named_after_its_file_in_the_results(tmp_path):
    path = export_zip(load_policy("reference"), tmp_path / "my-policy.onnx")
    document = evaluation.evaluate(
        load_policy(path), ["bbbench/FlatBalance-v1"], episodes=1, workers=1
    ).document
    assert document["policy"]["name"] == "my-policy.onnx"


def test_a_policy_that_names_its_task_plays_only_tasks_whose_observation_means_the_same(
    capsys,
):
    """Swap-v0's and ConvoyTurns-v0's observations have one width and other fields: a file
    whose contract says Swap-v0 is not scored on ConvoyTurns-v0 (nor BeamCarry-v0's on
    Convoy-v0), while tasks of one layout (BeamCarry and BeamCarryBumps) both play it."""
    submissions = ROOT / "leaderboards" / "submissions"
    swap_file = submissions / "ippo-swap-v0-3m" / "runs" / "s0" / "policy.onnx"
    swap = load_policy(swap_file)
    assert evaluation.select_tasks(swap, None) == ["bbbench/Swap-v0"]
    beam = load_policy(submissions / "ippo-beamcarry-v0-3m" / "runs" / "s0" / "policy.onnx")
    assert evaluation.select_tasks(beam, None) == [
        "bbbench/BeamCarry-v0",
        "bbbench/BeamCarryBumps-v0",
    ]
    assert beam.mismatch("bbbench/Convoy-v0") == (
        "its metadata says it was trained on bbbench/BeamCarry-v0, whose observation means "
        "other things than bbbench/Convoy-v0's (value 5 is 'hinge_force_along' there, "
        "'stretch_ahead' here)"
    )
    code = main(["eval", str(swap_file), "--task",
                 "bbbench/ConvoyTurns-v0", "--episodes", "1", "--workers", "1"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1
    assert "(value 8 is 'goal_distance' there, 'target_yaw_rate' here)" in err

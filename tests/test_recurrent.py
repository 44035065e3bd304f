"""ONNX's GRU on portable arithmetic (`bbbench.policies.onnx.recurrent`): its parity with
torch's GRU, its place in a graph bbbench reads, and the GRUs it refuses."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import bbbench
from bbbench.evaluation import evaluate
from bbbench.evaluation.play import Lockstep, MultiEpisode
from bbbench.evaluation.results import dumps
from bbbench.policies import PolicyError
from bbbench.policies.onnx import interpreter
from bbbench.policies.onnx.export import onnx_bytes
from bbbench.policies.onnx.policy import OnnxPolicy
from bbbench.policies.onnx.reader import parse_onnx
from bbbench.policies.onnx.recurrent import GruCell, run_gru

TASK = "bbbench/MultiBalance-v1"  # a width-17 observation, Discrete(9)


def onnx_weights(gru: torch.nn.GRU) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """torch's one-layer GRU as ONNX's W, R and B (gates r, z, n to z, r, h)."""

    def reorder(tensor: torch.Tensor) -> np.ndarray:
        r, z, n = tensor.detach().numpy().reshape(3, -1, *tensor.shape[1:])
        return np.concatenate([z, r, n])

    w, r = reorder(gru.weight_ih_l0), reorder(gru.weight_hh_l0)
    b = np.concatenate([reorder(gru.bias_ih_l0), reorder(gru.bias_hh_l0)])
    return w, r, b


def test_the_cell_matches_torchs_gru_to_float32s_last_bits_over_a_long_sequence():
    torch.manual_seed(0)
    gru = torch.nn.GRU(input_size=6, hidden_size=16)
    x = torch.randn(200, 5, 6)
    h0 = torch.randn(1, 5, 16) * 0.5
    with torch.no_grad():
        expected, last = gru(x, h0)
    cell = GruCell(*onnx_weights(gru), before_reset=True)
    y = run_gru({"cell": cell}, x.numpy(), h0.numpy())
    assert y.shape == (200, 1, 5, 16)
    assert y.dtype == np.float32
    np.testing.assert_allclose(y[:, 0], expected.numpy(), rtol=0, atol=2e-6)
    np.testing.assert_allclose(y[-1, 0], last[0].numpy(), rtol=0, atol=2e-6)


def test_linear_before_reset_0_is_onnxs_other_cell():
    """ONNX's default cell, r applied to h before its layer, written out in float64."""
    rng = np.random.default_rng(3)
    hidden, size = 4, 3
    w, r = rng.normal(size=(3 * hidden, size)), rng.normal(size=(3 * hidden, hidden))
    b = rng.normal(size=6 * hidden)
    x, h = rng.normal(size=(2, size)).astype(np.float32), np.zeros((2, hidden), np.float32)
    cell = GruCell(w.astype(np.float32), r.astype(np.float32), b.astype(np.float32), False)
    got = cell.step(x, h)
    w, r, b = (a.astype(np.float32).astype(np.float64) for a in (w, r, b))
    sig = lambda v: 1 / (1 + np.exp(-v))  # noqa: E731
    z = sig(x @ w[:hidden].T + h @ r[:hidden].T + b[:hidden] + b[3 * hidden : 4 * hidden])
    rr = sig(
        x @ w[hidden : 2 * hidden].T + h @ r[hidden : 2 * hidden].T
        + b[hidden : 2 * hidden] + b[4 * hidden : 5 * hidden]
    )  # fmt: skip
    n = np.tanh(x @ w[2 * hidden :].T + (rr * h) @ r[2 * hidden :].T + b[2 * hidden : 3 * hidden]
                + b[5 * hidden :])  # fmt: skip
    np.testing.assert_allclose(got, (1 - z) * n + z * h, rtol=0, atol=1e-6)


class _GruActor(torch.nn.Module):
    """An observation through a GRU cell from a zero state, then a linear head: the shape
    of a recurrent actor's graph (its state in and out are the next step)."""

    def __init__(self) -> None:
        super().__init__()
        torch.manual_seed(1)
        self.gru = torch.nn.GRU(input_size=17, hidden_size=12)
        self.head = torch.nn.Linear(12, 9)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        out, _ = self.gru(obs.unsqueeze(0))
        return self.head(out[0])


def test_an_exported_gru_graph_is_read_and_scores_as_torch_does(tmp_path):
    actor = _GruActor().eval()
    content = onnx_bytes(actor, TASK, algorithm="GRU test")
    assert b"GRU" in content
    policy = OnnxPolicy(parse_onnx(content, "gru.onnx", "gru.onnx"))
    observations = np.random.default_rng(0).normal(size=(64, 17)).astype(np.float32)
    with torch.no_grad():
        expected = actor(torch.from_numpy(observations)).numpy()
    scores = policy.actor(TASK).program(observations)
    np.testing.assert_allclose(scores, expected, rtol=0, atol=1e-5)
    actions = policy.actor(TASK)(observations)
    assert actions == expected.argmax(axis=1).tolist()


def _gru_graph(**changes) -> bytes:
    """A one-GRU graph written with onnx's helper, with `changes` to its attributes or
    inputs, as a hostile or foreign file would have them."""
    from onnx import TensorProto, helper, numpy_helper

    hidden, size = 4, 17
    rng = np.random.default_rng(0)
    w = numpy_helper.from_array(rng.normal(size=(1, 3 * hidden, size)).astype(np.float32), "W")
    r = numpy_helper.from_array(rng.normal(size=(1, 3 * hidden, hidden)).astype(np.float32), "R")
    head = numpy_helper.from_array(rng.normal(size=(hidden, 9)).astype(np.float32), "head")
    axes = numpy_helper.from_array(np.array([0], dtype=np.int64), "axes")
    axes_y = numpy_helper.from_array(np.array([0, 1], dtype=np.int64), "axes_y")
    attributes = {"hidden_size": hidden, **changes.pop("attributes", {})}
    inputs = changes.pop("inputs", ["x", "W", "R"])
    nodes = [
        helper.make_node("Unsqueeze", ["obs", "axes"], ["x"]),
        helper.make_node("GRU", inputs, ["y", "y_h"], **attributes),
        helper.make_node("Squeeze", ["y", "axes_y"], ["h"]),
        helper.make_node("MatMul", ["h", "head"], ["logits"]),
    ]
    graph = helper.make_graph(
        nodes,
        "gru",
        [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", size])],
        [helper.make_tensor_value_info("logits", TensorProto.FLOAT, ["batch", 9])],
        [w, r, head, axes, axes_y],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    for key, value in (("bbbench.observation", "17"), ("bbbench.action_space", "Discrete(9)")):
        model.metadata_props.add(key=key, value=value)
    return model.SerializeToString()


def test_a_hand_written_gru_graph_plays():
    policy = OnnxPolicy(parse_onnx(_gru_graph(), "gru.onnx", "gru.onnx"))
    actions = policy.actor(TASK)(np.zeros((3, 17), dtype=np.float32))
    assert len(actions) == 3


@pytest.mark.parametrize(
    ("changes", "words"),
    [
        ({"attributes": {"direction": "bidirectional"}}, "direction 'bidirectional'"),
        ({"attributes": {"layout": 1}}, "layout 1 (batch first)"),
        ({"attributes": {"clip": 3.0}}, "a clipped cell"),
        ({"attributes": {"activations": ["Relu", "Tanh"]}}, "activations other than"),
        ({"inputs": ["x", "W", "R", "", "obs"]}, "sequence_lens"),
        ({"attributes": {"hidden_size": 5}}, "are not one forward layer of 5 units"),
    ],
)
def test_a_gru_bbbench_does_not_run_is_refused_by_name(changes, words):
    with pytest.raises(PolicyError, match="GRU") as raised:
        OnnxPolicy(parse_onnx(_gru_graph(**changes), "gru.onnx", "gru.onnx"))
    assert words in str(raised.value)


class _RecurrentActor(torch.nn.Module):
    """A recurrent actor as `onnx_bytes(state_width=...)` exports it: (obs, state) in,
    (scores, next state) out."""

    def __init__(self, hidden: int = 12) -> None:
        super().__init__()
        torch.manual_seed(2)
        self.gru = torch.nn.GRU(input_size=17, hidden_size=hidden)
        self.head = torch.nn.Linear(hidden, 9)

    def forward(self, obs: torch.Tensor, state: torch.Tensor):
        out, last = self.gru(obs.unsqueeze(0), state.unsqueeze(0))
        return self.head(out[0]), last[0]


def _recurrent_policy(**options) -> OnnxPolicy:
    content = onnx_bytes(_RecurrentActor().eval(), TASK, algorithm="GRU", state_width=12, **options)
    return OnnxPolicy(parse_onnx(content, "gru.onnx", "gru.onnx"))


def test_a_recurrent_policy_carries_its_state_as_torch_does_over_a_sequence():
    policy = _recurrent_policy()
    actor = policy.actor(TASK)
    assert actor.state_width == 12
    assert policy.record()["contract"]["recurrent_state"] == 12
    rng = np.random.default_rng(5)
    states = actor.initial_state(4)
    module = _RecurrentActor().eval()
    h = torch.zeros(4, 12)
    for _ in range(50):
        observations = rng.normal(size=(4, 17)).astype(np.float32)
        actions, states = actor.step(observations, states)
        with torch.no_grad():
            scores, h = module(torch.from_numpy(observations), h)
        np.testing.assert_allclose(states, h.numpy(), rtol=0, atol=2e-5)
        assert actions == scores.numpy().argmax(axis=1).tolist()
    with pytest.raises(PolicyError, match="acts with its state"):
        actor(np.zeros((1, 17), dtype=np.float32))


class _Forgetting:
    """A recurrent actor fed zeros for its state at every step: what the loops would play
    if they dropped the state."""

    def __init__(self, actor) -> None:
        self.actor, self.state_width = actor, actor.state_width

    def initial_state(self, rows: int) -> np.ndarray:
        return self.actor.initial_state(rows)

    def step(self, observations, states, rngs=None):
        return self.actor.step(observations, np.zeros_like(states), rngs)


def test_the_play_loops_hand_each_bot_its_own_state_and_replay_the_same_bytes():
    policy = _recurrent_policy()
    first = evaluate(policy, [TASK], episodes=2, workers=1)
    again = evaluate(policy, [TASK], episodes=2, workers=1)
    assert dumps(first.document) == dumps(again.document)
    env = bbbench.make_parallel(TASK)
    seed = bbbench.spec(TASK).eval_seeds[0]
    carried = MultiEpisode(env, policy.actor(TASK), seed).play()
    forgotten = MultiEpisode(env, _Forgetting(policy.actor(TASK)), seed).play()
    assert carried.record() == first.document["tasks"][0]["episodes"][0]
    assert carried.episode_return != forgotten.episode_return  # the state matters


def test_single_bot_lanes_carry_their_states_and_drop_a_lane_that_ends():
    """Lockstep: lanes end at different steps (falls), and each keeps its own state row."""
    policy = _recurrent_policy()
    actor = policy.actor(TASK)
    task = "bbbench/FlatBalance-v1"
    content = onnx_bytes(_SoloRecurrent().eval(), task, state_width=12)
    solo = OnnxPolicy(parse_onnx(content, "solo.onnx", "solo.onnx")).actor(task)
    seeds = bbbench.spec(task).eval_seeds[:4]
    together = Lockstep([bbbench.make(task) for _ in seeds], solo, seeds).play()
    alone = [Lockstep([bbbench.make(task)], solo, [seed]).play()[0] for seed in seeds]
    assert together == alone
    assert len({episode.length for episode in together}) > 1  # lanes ended apart
    assert actor.state_width == 12


class _SoloRecurrent(_RecurrentActor):
    def __init__(self) -> None:
        super().__init__()
        torch.manual_seed(3)
        self.gru = torch.nn.GRU(input_size=5, hidden_size=12)


class _Misshapen(_RecurrentActor):
    """Gives back a state narrower than the one it takes."""

    def forward(self, obs, state):
        scores, last = super().forward(obs, state)
        return scores, last[:, :6]


def _with_metadata(content: bytes, **changes: str | None) -> bytes:
    """An exported file with its metadata keys changed (None: dropped)."""
    import onnx

    model = onnx.ModelProto()
    model.ParseFromString(content)
    props = {p.key: p.value for p in model.metadata_props}
    for key, value in changes.items():
        props.pop(f"bbbench.{key}", None)
        if value is not None:
            props[f"bbbench.{key}"] = value
    del model.metadata_props[:]
    for key, value in props.items():
        model.metadata_props.add(key=key, value=value)
    return model.SerializeToString()


def _state_file(kind: str) -> bytes:
    recurrent = onnx_bytes(_RecurrentActor().eval(), TASK, state_width=12)
    if kind == "no state key":
        return _with_metadata(recurrent, recurrent_state=None)
    if kind == "no state in the graph":
        return _with_metadata(onnx_bytes(_GruActor().eval(), TASK), recurrent_state="12")
    if kind == "another width":
        return _with_metadata(recurrent, recurrent_state="8")
    if kind == "a misshapen next state":  # as another exporter wrote it (ours refuses to)
        import io

        raw = io.BytesIO()
        names = {"input_names": ["obs", "state"], "output_names": ["action", "next_state"]}
        axes = {name: {0: "batch"} for name in ("obs", "state", "action", "next_state")}
        example = (torch.zeros(2, 17), torch.zeros(2, 12))
        torch.onnx.export(
            _Misshapen().eval(), example, raw, dynamo=False, dynamic_axes=axes, **names
        )
        return _with_metadata(
            raw.getvalue(), observation="17", action_space="Discrete(9)", recurrent_state="12"
        )
    raise AssertionError(kind)


@pytest.mark.parametrize(
    ("kind", "fragment"),
    [
        ("no state key", "its graph takes a state ('state' in, 'next_state' out), but its"),
        ("no state in the graph", "its contract says it carries a state of 12"),
        ("another width", "its state input 'state' is 12 wide, but its contract says 8"),
        ("a misshapen next state", "its state output 'next_state' has shape (1, 6), not (1, 12)"),
    ],
)
def test_a_state_missing_or_misshapen_is_one_line_and_exit_2(tmp_path, capsys, kind, fragment):
    from bbbench.cli import main

    path = tmp_path / "gru.onnx"
    path.write_bytes(_state_file(kind))
    code = main(["eval", str(path), "--task", TASK, "--episodes", "1", "--workers", "1"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1, err
    assert fragment in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["gru.onnx"]


def test_torchs_one_gru_step_runs_as_one_fused_step_with_the_same_bits(monkeypatch):
    """The six reshaping steps torch writes around a recurrent actor's GRU are folded into
    one step; the fused program and the one step by step agree bit for bit."""
    content = onnx_bytes(_RecurrentActor().eval(), TASK, state_width=12)
    fused = OnnxPolicy(parse_onnx(content, "gru.onnx", "gru.onnx")).actor(TASK)
    assert [step.op for step in fused.program.prefix] == ["GruStep"]
    monkeypatch.setattr(interpreter, "fuse_gru_step", lambda steps, state: (steps, state))
    plain = OnnxPolicy(parse_onnx(content, "gru.onnx", "gru.onnx")).actor(TASK)
    assert "GRU" in [step.op for step in plain.program.prefix]
    rng = np.random.default_rng(9)
    a, b = fused.initial_state(4), plain.initial_state(4)
    for _ in range(100):
        observations = (3 * rng.normal(size=(4, 17))).astype(np.float32)
        actions_a, a = fused.step(observations, a)
        actions_b, b = plain.step(observations, b)
        assert actions_a == actions_b
        assert a.tobytes() == b.tobytes()

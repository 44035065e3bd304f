"""ONNX's GRU on portable arithmetic (`bbbench.policies.onnx.recurrent`): its parity with
torch's GRU, its place in a graph bbbench reads, and the GRUs it refuses."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from bbbench.policies import PolicyError
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

"""ONNX's `GRU` on portable arithmetic: the recurrent cell of a policy that carries a
state from step to step.

One layer, forward, gates in ONNX's order (z, r, h; torch stores r, z, n). For each
step t of X, from the state h (initial_h, or zeros):

    z = sigmoid(x W_z + h R_z + Wb_z + Rb_z)
    r = sigmoid(x W_r + h R_r + Wb_r + Rb_r)
    n = tanh(x W_h + Wb_h + r * (h R_h + Rb_h))      linear_before_reset = 1 (torch's)
    n = tanh(x W_h + (r * h) R_h + Wb_h + Rb_h)      linear_before_reset = 0
    h = (1 - z) * n + z * h

Each pre-activation is one `portable.Layer` over the concatenated inputs (the float32
nearest the exact sum; its two biases added once, in float64), the sigmoid and tanh
`portable`'s, and the rest float32 products and sums, which IEEE 754 rounds alike on
every CPU: the same bits everywhere. torch sums the same cell in another order, so the
two agree to float32's last bits, not bit for bit (tests/test_recurrent.py bounds it).
"""

from __future__ import annotations

import numpy as np

from bbbench import portable

F4 = np.dtype(np.float32)


class GruCell:
    """The layers of one GRU, from ONNX's W (3H, I), R (3H, H) and B (6H,) of its one
    direction."""

    def __init__(self, w: np.ndarray, r: np.ndarray, b: np.ndarray, before_reset: bool) -> None:
        hidden = r.shape[1]
        self.hidden, self.before_reset = hidden, before_reset
        w, r, b = (np.asarray(a, dtype=np.float64) for a in (w, r, b))
        wb, rb = b[: 3 * hidden], b[3 * hidden :]
        gates, cand = slice(0, 2 * hidden), slice(2 * hidden, 3 * hidden)
        if before_reset:
            # One layer over [x, h] gives z's and r's pre-activations, x W_h + Wb_h and
            # h R_h + Rb_h: a zero block adds nothing to an exact sum.
            size = w.shape[1]
            weight = np.zeros((size + hidden, 4 * hidden))
            weight[:size, : 2 * hidden] = w[gates].T
            weight[size:, : 2 * hidden] = r[gates].T
            weight[:size, 2 * hidden : 3 * hidden] = w[cand].T
            weight[size:, 3 * hidden :] = r[cand].T
            bias = np.concatenate([wb[gates] + rb[gates], wb[cand], rb[cand]])
            self.layer = portable.Layer(weight, bias)
        else:  # z and r from [x, h]; the candidate from [x, r * h]
            self.layer = portable.Layer(
                np.concatenate([w[gates].T, r[gates].T]), wb[gates] + rb[gates]
            )
            self.candidate = portable.Layer(
                np.concatenate([w[cand].T, r[cand].T]), wb[cand] + rb[cand]
            )

    def step(self, x: np.ndarray, h: np.ndarray) -> np.ndarray:
        """The next state of every row: x (k, I), h (k, H), float32."""
        hidden = self.hidden
        out = self.layer(np.concatenate([x, h], axis=1))
        gates = portable.sigmoid(out[:, : 2 * hidden])
        z, r = gates[:, :hidden], gates[:, hidden:]
        if self.before_reset:
            n = portable.tanh(out[:, 2 * hidden : 3 * hidden] + r * out[:, 3 * hidden :])
        else:
            n = portable.tanh(self.candidate(np.concatenate([x, r * h], axis=1)))
        return (np.float32(1.0) - z) * n + z * h


def run_gru(params, x: np.ndarray, initial_h: np.ndarray | None = None) -> np.ndarray:
    """ONNX GRU's Y, (seq, 1, batch, H), for X (seq, batch, I) and initial_h (1, batch,
    H) or zeros. `params["cell"]`: the `GruCell`."""
    cell = params["cell"]
    h = (
        np.zeros((x.shape[1], cell.hidden), dtype=F4)
        if initial_h is None
        else np.asarray(initial_h, dtype=F4).reshape(x.shape[1], cell.hidden)
    )
    outputs = []
    for t in range(x.shape[0]):
        h = cell.step(x[t], h)
        outputs.append(h)
    return np.stack(outputs)[:, None]


def bind_gru(compiler, node, inputs):
    """What a GRU node's kernel reads: its W, R and B (constants of the graph), its
    attributes (one forward layer, the default activations, no clip, batch second), and
    X with initial_h if given; a clear `PolicyError` for any other kind of GRU."""
    attributes = node.attributes
    if attributes.get("direction", "forward") != "forward":
        raise compiler.fail(node, f"direction {attributes['direction']!r}: bbbench runs forward")
    if attributes.get("layout", 0) != 0:
        raise compiler.fail(node, "layout 1 (batch first): export with the sequence first")
    if tuple(attributes.get("activations", ("Sigmoid", "Tanh"))) != ("Sigmoid", "Tanh"):
        raise compiler.fail(node, "activations other than Sigmoid and Tanh")
    if "clip" in attributes:
        raise compiler.fail(node, "a clipped cell (the clip attribute)")
    if len(node.inputs) > 4 and node.inputs[4]:
        raise compiler.fail(node, "sequence_lens: every row's sequence is the whole X")
    w = compiler.constant(node, 1, "W")
    r = compiler.constant(node, 2, "R")
    hidden = attributes.get("hidden_size", r.shape[-1] if r.ndim == 3 else 0)
    b = compiler.constant(node, 3, "B", optional=True)
    if b is None:
        b = np.zeros((1, 6 * hidden), dtype=np.float32)
    size = w.shape[-1] if w.ndim == 3 else 0
    if w.shape != (1, 3 * hidden, size) or r.shape != (1, 3 * hidden, hidden):
        raise compiler.fail(
            node,
            f"W {list(w.shape)} and R {list(r.shape)} are not one forward layer of "
            f"{hidden} units: [1, {3 * hidden}, input] and [1, {3 * hidden}, {hidden}]",
        )
    if b.shape != (1, 6 * hidden):
        raise compiler.fail(node, f"B {list(b.shape)}: expected [1, {6 * hidden}]")
    before_reset = attributes.get("linear_before_reset", 0)
    cell = GruCell(w[0], r[0], b[0], bool(before_reset))
    kept = [inputs[0]]
    if len(node.inputs) > 5 and node.inputs[5]:
        kept.append(compiler.value(node.inputs[5]))
    return kept, {"cell": cell}

"""The ONNX operators bbbench runs, each in one place: its kernel and its rule.

As in onnx's reference evaluator, an operator is one entry (`Operator`): the function
that computes it on numpy arrays (`run(params, *inputs)`, on `bbbench.portable`'s
arithmetic where rounding could differ between CPUs), and what it reads of its node
(`bind`: the attributes and constant inputs that become its `params`, with their
checks), the types it computes on, and the type it gives. The interpreter
(`bbbench.policies.onnx.interpreter`) compiles a graph with these entries and knows no
operator by name but the four that shape the graph itself: `Constant` and `Identity`
(names and values), `Gemm` and `MatMul` (layers).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

from bbbench import portable
from bbbench.policies.onnx.recurrent import bind_gru, run_gru

F4, F8, I8 = np.dtype(np.float32), np.dtype(np.float64), np.dtype(np.int64)
_ONNX_TYPES = {1: F4, 11: F8}  # Cast's `to`: float32, float64

Bind = Callable[[Any, Any, list], tuple[list, dict[str, Any]]]


@dataclasses.dataclass(frozen=True)
class Operator:
    """One ONNX operator.

    run: the kernel, `run(params, *inputs)`.
    bind: `bind(compiler, node, inputs) -> (inputs, params)`: what the kernel reads of
        the node (attributes, constant inputs; `compiler.constant`, `compiler.fail`);
        None: no parameters, every input.
    computes: "float" (float32 or float64 arithmetic), "float32" (portable's
        functions, float32 only), or "any" (it moves values: the integer tensors of
        shape arithmetic too).
    same_type: its inputs share one float type (a float64 constant meeting float32 is
        cast to float32, as a zip's float64 weights are).
    gives: the output's type from `(params, first input's type)`; None: the first
        input's.
    last_output: a second output, where the node names one, is the first's last entry
        along its first axis (a recurrent cell's final state, `Y_h` of its `Y`).
    """

    run: Callable[..., np.ndarray]
    bind: Bind | None = None
    computes: str = "float"
    same_type: bool = False
    gives: Callable[[dict[str, Any], np.dtype], np.dtype] | None = None
    last_output: bool = False


# -- kernels -----------------------------------------------------------------------


def _variadic(function):
    def run(params, first, *rest):
        out = first
        for other in rest:
            out = function(out, other)
        return out

    return run


def _elementwise(function):
    return lambda params, *args: function(*args)


def _leaky_relu(params, x):
    return np.where(x >= 0.0, x, x * params["alpha"])


def _elu(params, x):
    negative = portable.expm1(x)
    if params["alpha"] != 1.0:
        negative = negative * params["alpha"]
    return np.where(x > 0.0, x, negative)


def clip(params, x):
    """`Clip` between `params["low"]` and `params["high"]` (None: unbounded)."""
    if params["low"] is None and params["high"] is None:
        return x
    return np.clip(x, params["low"], params["high"])


def _reshape(params, x, computed=None):
    shape = list(params["shape"] if computed is None else computed.tolist())
    for i, size in enumerate(shape):
        if size == 0 and not params["allowzero"]:
            shape[i] = x.shape[i]
    return x.reshape(shape)


def _flatten(params, x):
    axis = params["axis"] % (x.ndim + 1) if params["axis"] < 0 else params["axis"]
    return x.reshape(int(np.prod(x.shape[:axis], dtype=np.int64)), -1)


def _slice(params, x):
    index = [slice(None)] * x.ndim
    for start, end, axis, step in params["slices"]:
        index[axis] = slice(start, end, step)
    return x[tuple(index)]


# The most values a ConstantOfShape may make (a recurrent cell's zero state is hundreds).
MAX_FILLED = 1_000_000


def _constant_of_shape(params, shape):
    dims = tuple(int(size) for size in np.asarray(shape).reshape(-1))
    if any(size < 0 for size in dims) or np.prod(dims, dtype=np.float64) > MAX_FILLED:
        raise ValueError(f"a shape of {list(dims)}: at most {MAX_FILLED:,} values")
    return np.full(dims, params["value"], dtype=params["value"].dtype)


def reduce(params, x):
    """`ReduceMax`, `ReduceSum` and `ReduceMean` (`params["kind"]`): sums in float64,
    one slot after another, in the same order on every CPU, then rounded once."""
    axes = params["axes"]
    if axes is None:
        if params["noop"]:
            return x
        axes = tuple(range(x.ndim))
    axes = tuple(sorted(a % x.ndim for a in axes))
    if params["kind"] == "max":
        return np.max(x, axis=axes, keepdims=bool(params["keepdims"]))
    moved = np.moveaxis(x, axes, tuple(range(len(axes))))
    parts = moved.reshape(-1, *moved.shape[len(axes) :])
    total = np.zeros(parts.shape[1:], dtype=np.float64)
    for part in parts:
        total += part
    if params["kind"] == "mean":
        total /= len(parts)
    out = total.astype(x.dtype)
    if params["keepdims"]:
        out = np.expand_dims(out, axes)
    return out


# -- rules: what each reads of its node ----------------------------------------------


def _alpha(default: float) -> Bind:
    def bind(compiler, node, inputs):
        return inputs, {"alpha": np.float32(node.attributes.get("alpha", default))}

    return bind


def _bind_clip(compiler, node, inputs):
    kind = compiler.dtype(inputs[0])
    bounds = [compiler.constant(node, i, what, True) for i, what in ((1, "min"), (2, "max"))]
    low, high = (None if b is None else np.asarray(b, dtype=kind).reshape(()) for b in bounds)
    return inputs[:1], {"low": low, "high": high}


def _bind_cast(compiler, node, inputs):
    to = node.attributes.get("to")
    if to not in _ONNX_TYPES:
        raise compiler.fail(
            node, f"casts to ONNX type {to}; bbbench computes in float32 or float64"
        )
    return inputs, {"to": _ONNX_TYPES[to]}


def _bind_reshape(compiler, node, inputs):
    params: dict[str, Any] = {"allowzero": node.attributes.get("allowzero", 0)}
    shape = inputs[1] if len(inputs) > 1 else None
    if isinstance(shape, np.ndarray):
        params["shape"] = tuple(int(v) for v in shape.ravel())
        return inputs[:1], params
    if shape is None or compiler.types[shape] != I8:
        raise compiler.fail(node, "needs its shape, int64")
    return inputs, params


def _bind_shape(compiler, node, inputs):
    return inputs, {"start": node.attributes.get("start", 0), "end": node.attributes.get("end")}


def _bind_flatten(compiler, node, inputs):
    return inputs, {"axis": node.attributes.get("axis", 1)}


def _bind_slice(compiler, node, inputs):
    starts, ends = (compiler.constant(node, i, w).ravel() for i, w in ((1, "starts"), (2, "ends")))
    axes = compiler.constant(node, 3, "axes", optional=True)
    steps = compiler.constant(node, 4, "steps", optional=True)
    axes = range(len(starts)) if axes is None else axes.ravel()
    steps = [1] * len(starts) if steps is None else steps.ravel()
    if not len(starts) == len(ends) == len(axes) == len(steps) or 0 in list(steps):
        raise compiler.fail(node, "starts, ends, axes and steps disagree (or a step is 0)")
    slices = tuple(
        (int(s), int(e), int(a), int(t))
        for s, e, a, t in zip(starts, ends, axes, steps, strict=True)
    )
    return inputs[:1], {"slices": slices}


def _bind_concat(compiler, node, inputs):
    if "axis" not in node.attributes:
        raise compiler.fail(node, "needs its axis")
    return inputs, {"axis": node.attributes["axis"]}


def _axes(compiler, node, since: int):
    """The axes of a node that took them as an attribute before opset `since`, and as its
    second input from then on."""
    if compiler.model.opset >= since:
        axes = compiler.constant(node, 1, "axes", optional=True)
        return None if axes is None or axes.size == 0 else tuple(int(a) for a in axes.ravel())
    axes = node.attributes.get("axes")
    return None if axes is None else tuple(axes)


def _bind_squeeze(compiler, node, inputs):
    return inputs[:1], {"axes": _axes(compiler, node, 13)}


def _bind_unsqueeze(compiler, node, inputs):
    axes = _axes(compiler, node, 13)
    if axes is None:
        raise compiler.fail(node, "needs its axes")
    return inputs[:1], {"axes": axes}


def _bind_gather(compiler, node, inputs):
    indices = compiler.constant(node, 1, "indices").astype(np.int64)
    return inputs[:1], {"indices": indices, "axis": node.attributes.get("axis", 0)}


def _bind_constant_of_shape(compiler, node, inputs):
    value = node.attributes.get("value", np.zeros(1, dtype=F4))
    if value.size != 1 or value.dtype not in (F4, F8, I8):
        raise compiler.fail(node, "its value must be one float32, float64 or int64")
    return inputs[:1], {"value": value.reshape(())}


def _bind_reduce(kind: str, since: int) -> Bind:
    def bind(compiler, node, inputs):
        attributes = node.attributes
        params = {
            "kind": kind,
            "axes": _axes(compiler, node, since),
            "keepdims": attributes.get("keepdims", 1),
            "noop": attributes.get("noop_with_empty_axes", 0),
        }
        return inputs[:1], params

    return bind


# -- the table ------------------------------------------------------------------------

TABLE: dict[str, Operator] = {
    "Add": Operator(_variadic(np.add), same_type=True),
    "Sub": Operator(_elementwise(np.subtract), same_type=True),
    "Mul": Operator(_variadic(np.multiply), same_type=True),
    "Div": Operator(_elementwise(np.divide), same_type=True),
    "Max": Operator(_variadic(np.maximum), same_type=True),
    "Min": Operator(_variadic(np.minimum), same_type=True),
    "Neg": Operator(_elementwise(np.negative)),
    "Relu": Operator(lambda params, x: np.maximum(x, 0.0)),
    "LeakyRelu": Operator(_leaky_relu, _alpha(0.01)),
    "Elu": Operator(_elu, _alpha(1.0), computes="float32"),
    "Tanh": Operator(lambda params, x: portable.tanh(x), computes="float32"),
    "Sigmoid": Operator(lambda params, x: portable.sigmoid(x), computes="float32"),
    "Clip": Operator(clip, _bind_clip),
    "Cast": Operator(
        lambda params, x: x.astype(params["to"]), _bind_cast, gives=lambda p, _: p["to"]
    ),
    "Reshape": Operator(_reshape, _bind_reshape, computes="any"),
    "Flatten": Operator(_flatten, _bind_flatten, computes="any"),
    "Slice": Operator(_slice, _bind_slice, computes="any"),
    "Concat": Operator(
        lambda params, *xs: np.concatenate(xs, axis=params["axis"]),
        _bind_concat,
        computes="any",
        same_type=True,
    ),
    "Squeeze": Operator(
        lambda params, x: (
            np.squeeze(x) if params["axes"] is None else np.squeeze(x, axis=params["axes"])
        ),
        _bind_squeeze,
        computes="any",
    ),
    "Unsqueeze": Operator(
        lambda params, x: np.expand_dims(x, params["axes"]), _bind_unsqueeze, computes="any"
    ),
    "Gather": Operator(
        lambda params, x: np.take(x, params["indices"], axis=params["axis"]),
        _bind_gather,
        computes="any",
    ),
    "Shape": Operator(
        lambda params, x: np.array(x.shape[params["start"] : params["end"]], dtype=I8),
        _bind_shape,
        computes="any",
        gives=lambda p, _: I8,
    ),
    "ReduceMax": Operator(reduce, _bind_reduce("max", 18)),
    "ReduceSum": Operator(reduce, _bind_reduce("sum", 13)),
    "ReduceMean": Operator(reduce, _bind_reduce("mean", 18)),
    "ConstantOfShape": Operator(
        _constant_of_shape,
        _bind_constant_of_shape,
        computes="any",
        gives=lambda p, _: p["value"].dtype,
    ),
    "GRU": Operator(run_gru, bind_gru, computes="float32", last_output=True),
}

# The operators the interpreter itself turns into the graph's names, values and layers.
STRUCTURAL = frozenset({"Constant", "Identity", "Gemm", "MatMul"})
# The ONNX operators bbbench runs (the rest is refused by name when the file is read).
OPERATORS = frozenset(TABLE) | STRUCTURAL

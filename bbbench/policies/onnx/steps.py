"""The steps a compiled ONNX graph is made of, and the two things the compiler fuses:
VecNormalize's arithmetic into one step, and a chain of layers and one kind of
activation into an `MlpActor` (`bbbench.policies.onnx.interpreter`)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from bbbench.policies.onnx.operators import F4, F8


@dataclasses.dataclass(frozen=True, eq=False)
class Step:
    """One operation: `inputs` are tensor names (str) or constants (arrays)."""

    op: str
    inputs: tuple
    output: str
    params: dict[str, Any]
    label: str  # the node, for error messages


# ONNX activations that are an `MlpActor` activation (with their default attributes).
_MLP_ACTIVATIONS = {"Tanh": "Tanh", "Relu": "ReLU", "Sigmoid": "Sigmoid"}


def fuse_normalization(steps: list[Step], source: str) -> list[Step]:
    """The first five steps as one when they are VecNormalize's arithmetic on the input
    (as `bbbench export` and `export_onnx` write it): Cast to float64, Sub and Div by
    constants, Clip, Cast to float32, each result used once."""
    ops = [(step.op, step.params.get("to")) for step in steps[:5]]
    if ops != [("Cast", F8), ("Sub", None), ("Div", None), ("Clip", None), ("Cast", F4)]:
        return steps
    cast, sub, div, bounds, back = steps[:5]
    chain = [source, cast.output, sub.output, div.output, bounds.output]
    if [step.inputs[0] for step in steps[:5]] != chain or not all(
        isinstance(step.inputs[1], np.ndarray) for step in (sub, div)
    ):
        return steps
    used = [x for step in steps[5:] for x in step.inputs if isinstance(x, str)]
    if any(name in used for name in chain[1:]):
        return steps
    params = {
        "mean": sub.inputs[1],
        "std": div.inputs[1],
        "low": bounds.params["low"],
        "high": bounds.params["high"],
    }
    fused = Step("Normalize", (source,), back.output, params, "VecNormalize's arithmetic")
    return [fused, *steps[5:]]


def mlp_segment(steps: list[Step], output: str, shapes) -> tuple[list[int], str] | None:
    """The step indices of the longest chain layer, activation, layer ... ending in the last
    layer, every link used once and 2-D, with one kind of activation; and its activation."""
    uses: dict[str, int] = {output: 1}
    producer: dict[str, int] = {}
    for i, step in enumerate(steps):
        producer[step.output] = i
        for x in step.inputs:
            if isinstance(x, str):
                uses[x] = uses.get(x, 0) + 1
    layers = [i for i, step in enumerate(steps) if step.op == "Linear"]
    if not layers:
        return None
    two_d = lambda name: shapes is None or len(shapes.get(name, ())) == 2  # noqa: E731
    head = layers[-1]
    if not (two_d(steps[head].inputs[0]) and two_d(steps[head].output)):
        return None
    chain, activation = [head], None
    while True:
        source = steps[chain[0]].inputs[0]
        act_index = producer.get(source)
        if act_index is None or uses.get(source) != 1:
            break
        act = steps[act_index]
        kind = _MLP_ACTIVATIONS.get(act.op) or _mlp_activation(act)
        if kind is None or (activation is not None and kind != activation):
            break
        inner = act.inputs[0]
        layer_index = producer.get(inner) if isinstance(inner, str) else None
        if layer_index is None or uses.get(inner) != 1 or steps[layer_index].op != "Linear":
            break
        if not two_d(steps[layer_index].inputs[0]):
            break
        activation = kind
        chain[:0] = [layer_index, act_index]
    return chain, activation or "Tanh"


def _mlp_activation(step: Step) -> str | None:
    """LeakyRelu at torch's default slope and Elu at alpha 1: `MlpActor`'s."""
    if step.op == "LeakyRelu" and step.params["alpha"] == np.float32(0.01):
        return "LeakyReLU"
    if step.op == "Elu" and step.params["alpha"] == np.float32(1.0):
        return "ELU"
    return None

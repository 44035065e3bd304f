"""The steps a compiled ONNX graph is made of, and the three things the compiler fuses:
VecNormalize's arithmetic into one step, a recurrent actor's one GRU step and the
reshaping around it into one step, and a chain of layers and one kind of activation
into an `MlpActor` (`bbbench.policies.onnx.interpreter`)."""

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


def fuse_gru_step(steps: list[Step], state_output: str | None) -> tuple[list[Step], str | None]:
    """torch's export of one step of a one-layer GRU (`torch.nn.GRU` on a sequence of one,
    as `onnx_bytes(state_width=...)` writes a recurrent actor: Unsqueeze the observation
    and the state, GRU, Squeeze and Gather its Y, Gather its last output) as one
    `GruStep` whose output is both the features and the next state: the same cell on the
    same values, without the six reshaping steps around it. The steps and the state
    output's name, unchanged where the graph is not that."""
    producer = {step.output: i for i, step in enumerate(steps)}
    users: dict[str, list[int]] = {}
    for i, step in enumerate(steps):
        for x in step.inputs:
            if isinstance(x, str):
                users.setdefault(x, []).append(i)

    def only_user(name: str, op: str, **params) -> int | None:
        found = users.get(name, [])
        if len(found) != 1 or steps[found[0]].op != op:
            return None
        step = steps[found[0]]
        same = all(np.array_equal(step.params.get(k), v) for k, v in params.items())
        return found[0] if same else None

    for c, gru in enumerate(steps):
        if gru.op != "GRU" or len(gru.inputs) != 2 or state_output is None:
            continue
        unsqueezed = [producer.get(x) for x in gru.inputs]
        if None in unsqueezed or any(
            steps[u].op != "Unsqueeze" or tuple(steps[u].params.get("axes", ())) != (0,)
            or len(users[steps[u].output]) != 1
            for u in unsqueezed
        ):  # fmt: skip
            continue
        taken = sorted(users.get(gru.output, []))
        if len(taken) != 2:
            continue
        last = [i for i in taken if steps[i].op == "Gather"]
        squeeze = [i for i in taken if steps[i].op == "Squeeze"]
        if len(last) != 1 or len(squeeze) != 1:
            continue
        last, squeeze = last[0], squeeze[0]
        if not (
            np.array_equal(steps[last].params.get("indices"), -1)
            and steps[last].params.get("axis") == 0
            and tuple(steps[squeeze].params.get("axes", ())) == (1,)
        ):
            continue
        features = only_user(steps[squeeze].output, "Gather", indices=0, axis=0)
        state = only_user(steps[last].output, "Gather", indices=0, axis=0)
        if features is None or state is None or steps[state].output != state_output:
            continue
        if users.get(state_output):  # the next state feeds nothing but the graph's output
            continue
        out = steps[features].output
        sources = tuple(steps[u].inputs[0] for u in unsqueezed)
        fused = Step("GruStep", sources, out, gru.params, f"{gru.label}, one step")
        gone = {*unsqueezed, last, squeeze, features, state}
        kept = [s if i != c else fused for i, s in enumerate(steps) if i not in gone]
        return kept, out
    return steps, state_output

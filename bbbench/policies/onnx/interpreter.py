"""A small interpreter of ONNX policy graphs on portable arithmetic.

It runs the operators a policy network needs and no others (`bbbench.policies.onnx.operators`,
each kernel beside its rule):

- layers: `Gemm` (alpha = beta = 1, A not transposed) and `MatMul` by a constant
  matrix; a `MatMul` whose only use is an `Add` of a constant bias is one layer,
  as `Gemm` is. Each output is the float32 nearest the exact x . w + b
  (`bbbench.portable.Layer`), the same bits on every CPU, on any number of
  leading dimensions (the neighbour slots of a multi-bot observation);
- activations: `Tanh`, `Relu`, `LeakyRelu`, `Elu`, `Sigmoid` (`Sigmoid` then `Mul`
  is SiLU), float32, on `bbbench.portable`'s functions;
- arithmetic, exactly rounded by IEEE 754 on every CPU: `Add`, `Sub`, `Mul`,
  `Div`, `Neg`, `Max`, `Min`, `Clip`, and `Cast` between float32 and float64
  (bbbench export normalizes observations in float64 inside the graph, as
  VecNormalize does);
- shapes: `Reshape`, `Flatten`, `Slice`, `Concat`, `Squeeze`, `Unsqueeze`,
  `Gather` (constant indices), `Identity`, `Constant`, `ConstantOfShape` (torch's zero
  state of a GRU), and `Shape` (the int64 dimensions exporters gather to flatten a
  batch, as RLlib's does);
- pooling over slots: `ReduceMax`, and `ReduceSum` and `ReduceMean` summed in
  float64 in slot order, then rounded once (numpy's own sums change order with
  the CPU's vector width);
- recurrence: `GRU` (one forward layer, `bbbench.policies.onnx.recurrent`), its
  gates' layers and activations portable's.

A graph compiles to a `Program`. Its longest chain of layers and one kind of
activation, ending in the graph's last layer, becomes an `MlpActor` (the same
arithmetic, and for a Discrete policy the fast greedy path of a
stable-baselines3 zip); the nodes before and after it run one by one.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

from bbbench import portable
from bbbench.policies.errors import PolicyError, RefusedForSafety
from bbbench.policies.mlp import MlpActor
from bbbench.policies.onnx.operators import F4, I8, TABLE, clip
from bbbench.policies.onnx.steps import Step, fuse_gru_step, fuse_normalization, mlp_segment

# The most values any tensor may hold per observation (or in all, for a constant): a
# policy for these tasks needs thousands.
MAX_ROW_VALUES = 1_000_000


# -- the two steps the compiler makes itself -------------------------------------------


def _linear(params, x):
    layer = params["layer"]
    flat = x.reshape(-1, x.shape[-1])
    return layer(flat).reshape(*x.shape[:-1], layer.weight.shape[1])


def _normalize(params, x):
    """Cast to float64, Sub, Div, Clip, Cast to float32, in one: the same operations on
    the same values (numpy widens float32 to float64 exactly)."""
    scaled = (x - params["mean"]) / params["std"]
    return clip(params, scaled).astype(F4)


# Each step's kernel: an ONNX operator's (`bbbench.policies.onnx.operators`), or a layer's, or
# VecNormalize's arithmetic folded into one.
KERNELS: dict[str, Callable] = {
    **{name: operator.run for name, operator in TABLE.items()},
    "Linear": _linear,
    "Normalize": _normalize,
    "GruStep": lambda params, x, h: params["cell"].step(x, np.asarray(h, dtype=F4)),
}


# -- compiling a graph -----------------------------------------------------------


class _Compiler:
    """Turns checked nodes into `Step`s: constants folded and bound, layers formed, types
    checked (float32 or float64 arithmetic; layers on float32)."""

    def __init__(self, model) -> None:
        self.model = model
        self.where = model.name
        self.constants: dict[str, np.ndarray] = dict(model.constants)
        self.types: dict[str, np.dtype] = {model.input: F4}
        if model.state_input is not None:
            self.types[model.state_input] = F4
        self.alias: dict[str, str] = {}
        self.steps: list[Step] = []
        self.uses: dict[str, int] = {}
        for node in model.nodes:
            for name in node.inputs:
                self.uses[name] = self.uses.get(name, 0) + 1

    def fail(self, node, message: str) -> PolicyError:
        return PolicyError(f"{self.where}: {node.op} ({node.outputs[0]}): {message}")

    def name(self, name: str) -> str:
        return self.alias.get(name, name)

    def constant(self, node, index: int, what: str, optional: bool = False):
        if index >= len(node.inputs) or not node.inputs[index]:
            if optional:
                return None
            raise self.fail(node, f"needs its {what}")
        value = self.constants.get(self.name(node.inputs[index]))
        if value is None:
            raise self.fail(node, f"its {what} must be a constant of the graph")
        return value

    def value(self, name: str):
        """A bound input: the constant, or the tensor's name."""
        name = self.name(name)
        if name in self.constants:
            return self.constants[name]
        if name not in self.types:
            raise PolicyError(
                f"{self.where}: tensor {name!r} is used before any node computes it (the "
                f"graph must be in topological order)"
            )
        return name

    def dtype(self, value) -> np.dtype:
        return value.dtype if isinstance(value, np.ndarray) else self.types[value]

    def compile(self) -> list[Step]:
        nodes = list(self.model.nodes)
        skip: set[int] = set()
        for i, node in enumerate(nodes):
            if i in skip:
                continue
            fused = self._fused_bias(nodes, i)
            if fused is not None:
                skip.add(fused)
            self._node(node, nodes[fused] if fused is not None else None)
        output = self.output = self.name(self.model.output)
        if output not in self.types:
            raise PolicyError(f"{self.where}: no node computes the output {output!r}")
        if self.types[output] != F4:
            raise PolicyError(
                f"{self.where}: its output is {self.types[output]}; a bbbench policy outputs "
                f"float32 (cast it)"
            )
        if self.model.state_output is not None:
            state = self.state_output = self.name(self.model.state_output)
            if self.types.get(state) != F4:
                raise PolicyError(
                    f"{self.where}: its state output {state!r} is not a float32 tensor the "
                    f"graph computes"
                )
        return self.steps

    def _fused_bias(self, nodes, i: int) -> int | None:
        """The index of the `Add` of a constant bias that is a `MatMul`'s only use."""
        node = nodes[i]
        if node.op != "MatMul" or self.uses.get(node.outputs[0]) != 1:
            return None
        if node.outputs[0] == self.model.output:
            return None
        for j in range(i + 1, len(nodes)):
            add = nodes[j]
            if node.outputs[0] in add.inputs:
                if add.op != "Add" or len(add.inputs) != 2:
                    return None
                other = add.inputs[1 - add.inputs.index(node.outputs[0])]
                bias = self.constants.get(self.name(other))
                weight = self.constants.get(self.name(node.inputs[1]))
                if bias is None or weight is None or weight.ndim != 2 or bias.dtype.kind != "f":
                    return None
                if bias.size != weight.shape[1] or bias.shape[-1:] != (weight.shape[1],):
                    return None
                if any(size != 1 for size in bias.shape[:-1]):
                    return None
                return j
        return None

    def _node(self, node, fused_add) -> None:
        op, output = node.op, node.outputs[0]
        if op == "Constant":
            self.constants[output] = self._constant_value(node)
            return
        if op == "Identity":
            source = self.name(node.inputs[0])
            self.alias[output] = source
            if source in self.types:
                self.types[output] = self.types[source]
            return
        if op in ("Gemm", "MatMul"):
            self._layer(node, fused_add)
            return
        operator = TABLE[op]
        inputs = [self.value(name) for name in node.inputs if name]
        if operator.same_type:
            inputs = self._same_type(node, inputs)
        params: dict[str, Any] = {}
        if operator.bind is not None:
            inputs, params = operator.bind(self, node, inputs)
        kinds = {self.dtype(x) for x in inputs}
        if operator.computes != "any" and any(kind.kind != "f" for kind in kinds):
            raise self.fail(node, "computes on integers; bbbench runs float arithmetic only")
        if operator.computes == "float32" and kinds != {F4}:
            raise self.fail(node, "runs on float32 only (portable arithmetic)")
        step = Step(op, tuple(inputs), output, params, f"{op} ({output})")
        if all(isinstance(x, np.ndarray) for x in inputs):  # fold it now
            value = self.constants[output] = _run_step(step, {}, self.where)
            _check_size(self.where, step.label, value.size, 1)
            return
        first = self.dtype(inputs[0])
        self.types[output] = first if operator.gives is None else operator.gives(params, first)
        self.steps.append(step)
        if operator.last_output and len(node.outputs) > 1 and node.outputs[1]:
            last = node.outputs[1]  # the first output's last entry (GRU's Y_h)
            params = {"indices": np.int64(-1), "axis": 0}
            self.steps.append(Step("Gather", (output,), last, params, f"{op} ({last})"))
            self.types[last] = self.types[output]

    def _same_type(self, node, inputs: list) -> list:
        """Inputs of one float type: a float64 constant meeting float32 arithmetic is cast
        to float32 (as a zip's float64 weights are)."""
        computed = {self.types[x] for x in inputs if isinstance(x, str)}
        if len(computed) > 1:
            raise self.fail(node, "mixes float32 and float64 tensors")
        if computed:
            [kind] = computed
            inputs = [
                x.astype(kind) if isinstance(x, np.ndarray) and x.dtype.kind == "f" else x
                for x in inputs
            ]
        return inputs

    def _layer(self, node, fused_add) -> None:
        attributes = node.attributes
        if node.op == "Gemm":
            if attributes.get("alpha", 1.0) != 1.0 or attributes.get("beta", 1.0) != 1.0:
                raise self.fail(node, "alpha and beta must be 1 (fold them into the weights)")
            if attributes.get("transA", 0):
                raise self.fail(node, "a transposed A (transA=1) is not a layer's input")
        weight = self.constant(node, 1, "weight (B)")
        if weight.ndim != 2 or weight.dtype.kind != "f":
            raise self.fail(node, f"its weight must be a float matrix, got shape {weight.shape}")
        if attributes.get("transB", 0):
            weight = weight.T
        if node.op == "Gemm":
            bias = self.constant(node, 2, "bias (C)", optional=True)
        else:
            bias = None
            if fused_add is not None:
                other = next(n for n in fused_add.inputs if n != node.outputs[0])
                bias = self.constants[self.name(other)]
        out = weight.shape[1]
        if bias is None:
            bias = np.zeros(out, dtype=np.float32)
        try:
            bias = np.broadcast_to(bias, (out,)) if bias.ndim <= 1 else bias.reshape(out)
        except ValueError:
            raise self.fail(node, f"a bias of shape {bias.shape} for {out} outputs") from None
        source = self.value(node.inputs[0])
        if isinstance(source, np.ndarray) or self.types[source] != F4:
            raise self.fail(node, "a layer's input must be the float32 tensor the graph computes")
        layer = portable.Layer(weight.astype(np.float32), bias.astype(np.float32))
        output = fused_add.outputs[0] if fused_add is not None else node.outputs[0]
        params = {
            "layer": layer,
            "weights": (
                np.ascontiguousarray(weight, dtype=np.float32),
                np.ascontiguousarray(bias, dtype=np.float32),
            ),
        }
        self.steps.append(Step("Linear", (source,), output, params, f"{node.op} ({output})"))
        self.types[output] = F4

    def _constant_value(self, node) -> np.ndarray:
        attributes = node.attributes
        if "value" in attributes:
            return attributes["value"]
        for key, dtype in (
            ("value_float", F4),
            ("value_floats", F4),
            ("value_int", I8),
            ("value_ints", I8),
        ):
            if key in attributes:
                return np.array(attributes[key], dtype=dtype)
        raise self.fail(node, "a Constant of a kind bbbench does not read")


def _check_size(where: str, label: str, size: int, rows: int) -> None:
    if size > MAX_ROW_VALUES * rows:
        raise RefusedForSafety(
            f"{where}: {label} makes a tensor of {size:,} values ({rows} observation(s)), "
            f"more than the {MAX_ROW_VALUES:,} a row bbbench computes"
        )


def _run_step(step: Step, env: dict, where: str):
    args = [env[x] if isinstance(x, str) else x for x in step.inputs]
    try:
        return KERNELS[step.op](step.params, *args)
    except (ValueError, IndexError, TypeError, np.exceptions.AxisError) as error:
        raise PolicyError(f"{where}: {step.label} fails: {str(error)[:200]}") from None


def _run(steps, env: dict, where: str, check=None) -> dict:
    """`env` with every step's output; `check(step, value)` after each, if given."""
    if not steps:
        return env
    with np.errstate(all="ignore"):  # a division by zero gives inf, as in float32
        for step in steps:
            value = env[step.output] = _run_step(step, env, where)
            if check is not None:
                check(step, value)
    return env


# -- the program -----------------------------------------------------------------


@dataclasses.dataclass(frozen=True, eq=False)
class Program:
    """A compiled graph: `prefix` steps, then an `MlpActor` (if the graph has a chain of
    layers), then `suffix` steps. Holds numpy arrays only: it pickles into workers."""

    where: str
    input: str
    output: str
    prefix: tuple[Step, ...]
    mlp: MlpActor | None
    mlp_input: str | None
    mlp_output: str | None
    suffix: tuple[Step, ...]
    state_input: str | None = None  # a recurrent graph's state in and out
    state_output: str | None = None

    def step(self, observations: np.ndarray, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A recurrent graph's output and next states for a batch of observations and each
        row's state (float32, (k, n) and (k, N))."""
        env = self._values({self.input: observations, self.state_input: states})
        return env[self.output], env[self.state_output]

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        """The graph's output for a batch of observations (float32, (k, n))."""
        if self.mlp is not None and not self.suffix and self.output == self.mlp_output:
            return self.mlp.outputs(self._mlp_input(observations))
        return self._values({self.input: observations})[self.output]

    def _values(self, inputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Every value the graph computes from `inputs`: the prefix, the chain, the suffix."""
        env = _run(self.prefix, inputs, self.where)
        if self.mlp is not None:
            env[self.mlp_output] = self.mlp.outputs(env[self.mlp_input])
            env = _run(self.suffix, env, self.where)
        return env

    def greedy_mlp(self, observations: np.ndarray) -> list:
        """A Discrete policy whose graph ends in its chain: the chain's own actions (its fast
        greedy path)."""
        return self.mlp(self._mlp_input(observations))

    def _mlp_input(self, observations: np.ndarray) -> np.ndarray:
        prefix = self.prefix
        if not prefix:
            return observations
        if len(prefix) == 1 and prefix[0].op == "Normalize":  # as NormalizedActor does
            return _normalize(prefix[0].params, observations)
        return _run(prefix, {self.input: observations}, self.where)[self.mlp_input]


@dataclasses.dataclass(frozen=True)
class Steps:
    """A checked `OnnxModel`'s nodes as steps (constants folded, layers formed), once."""

    model: Any
    steps: tuple[Step, ...]
    output: str  # the graph's output, after aliases
    state_output: str | None = None  # a recurrent graph's next state, after aliases


def compile_steps(model) -> Steps:
    """The steps of a checked `OnnxModel`; `PolicyError` for a graph bbbench cannot run."""
    compiler = _Compiler(model)
    steps = compiler.compile()
    state = getattr(compiler, "state_output", None)
    return Steps(model, tuple(steps), compiler.output, state)


def compile_graph(
    compiled: Steps, discrete: bool, shapes: dict[str, tuple] | None = None
) -> Program:
    """The compiled steps as a `Program`. `shapes`: each tensor's shape on a trial batch
    (from `trial_shapes`); only 2-D layers join the `MlpActor`."""
    model = compiled.model
    steps, output = fuse_normalization(list(compiled.steps), model.input), compiled.output
    steps, state_output = fuse_gru_step(steps, compiled.state_output)
    state = (model.state_input, state_output)
    segment = mlp_segment(steps, output, shapes)
    if segment is None:
        return Program(model.name, model.input, output, tuple(steps), None, None, None, (), *state)
    chain, activation = segment
    members = set(chain)
    head = steps[chain[-1]]
    downstream = {head.output}
    suffix, prefix = [], []
    for i, step in enumerate(steps):
        if i in members:
            continue
        if any(isinstance(x, str) and x in downstream for x in step.inputs):
            downstream.add(step.output)
            suffix.append(step)
        else:
            prefix.append(step)
    layers = [steps[i].params["weights"] for i in chain if steps[i].op == "Linear"]
    mlp = MlpActor(
        hidden=tuple(layers[:-1]), activation=activation, head=layers[-1], output="argmax"
    )
    return Program(
        model.name,
        model.input,
        output,
        tuple(prefix),
        mlp,
        steps[chain[0]].inputs[0],
        head.output,
        tuple(suffix),
        *state,
    )


def trial_shapes(
    compiled: Steps, observations: np.ndarray, states: np.ndarray | None = None
) -> dict[str, tuple]:
    """Every computed tensor's shape on `observations` (and a recurrent graph's `states`),
    running the graph step by step;
    `RefusedForSafety` as soon as one holds more than `MAX_ROW_VALUES` values a row (a
    chain of Concats doubling a tensor grows it past any memory in 40 nodes)."""
    model = compiled.model

    def check(step: Step, value) -> None:
        _check_size(model.name, step.label, np.size(value), len(observations))

    env = {model.input: observations}
    if model.state_input is not None:
        env[model.state_input] = states
    env = _run(compiled.steps, env, model.name, check)
    env[model.output] = env[compiled.output]
    if compiled.state_output is not None:
        env[model.state_output] = env[compiled.state_output]
    return {name: np.shape(value) for name, value in env.items()}

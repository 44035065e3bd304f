"""Write policies as self-contained ONNX files with their contract inside.

- `export_zip`: a stable-baselines3 zip (with its VecNormalize statistics, folded
  into the graph) written as an ONNX graph of the layers bbbench already runs: the
  exported file plays byte for byte what the zip plays (checked before it is
  written, on observations across the task's bounds).
- `export_onnx`: any torch actor (a CleanRL agent's `actor`, an rsl_rl policy),
  with an optional observation normalizer, through `torch.onnx.export`.
- `export_foreign`: an ONNX file written by another library (RLlib's
  `export_policy_model(onnx=...)`, an Isaac Lab `policy.onnx`), reduced to the
  one output that acts and given the contract.

Every file is read back through bbbench's own safe reader before it is written
(atomically): what `bbbench export` writes, `bbbench eval` scores.
"""

from __future__ import annotations

import dataclasses
import tempfile
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from bbbench.files import write_atomic
from bbbench.policies.archive import read_file
from bbbench.policies.errors import PolicyError
from bbbench.policies.onnx.contract import Contract, describe_action_space, read_contract
from bbbench.policies.onnx.policy import OnnxPolicy
from bbbench.policies.onnx.reader import MAX_FILE_BYTES, check_safety, parse_onnx, parse_proto
from bbbench.policies.policy import NormalizedActor, Policy, fitting_tasks
from bbbench.tasks.suite import agent_spaces, group_spaces, spec

OPSET = 17
IR_VERSION = 8  # read by onnxruntime 1.10 and later
INPUT, OUTPUT = "obs", "action"
STATE_INPUT, STATE_OUTPUT = "state", "next_state"  # a recurrent actor's
_CHECK_ROWS = 4096


def export_zip(
    policy: Policy,
    out: str | Path,
    task_id: str | None = None,
    training_steps: int | None = None,
) -> Path:
    """Write `policy` (an `SB3ZipPolicy`, loaded with its statistics by `load_policy`) as
    ONNX at `out`: its network as Gemm layers, its normalization in float64 as
    VecNormalize computes it. `task_id`: a task it fits (default: the first)."""
    task_id = task_id or next(iter(fitting_tasks(policy)), None)
    if task_id is None:
        raise PolicyError(f"{policy.name}: fits no task of the suite; nothing to export for")
    reason = policy.mismatch(task_id)
    if reason:
        raise PolicyError(f"{policy.name} ({policy.spaces_text()}) cannot play {task_id}: {reason}")
    actor = policy.actor(task_id)
    normalization = actor.normalization if isinstance(actor, NormalizedActor) else None
    mlp = actor.actor if isinstance(actor, NormalizedActor) else actor
    contract = Contract(
        observation=policy.observation_shape[0],
        action_space=policy.action_space,
        algorithm=policy.algorithm,
        training_steps=training_steps,
        task=task_id,
    )
    graph = _Graph()
    x = INPUT
    if normalization is not None and normalization.normalize:
        x = graph.normalization(x, normalization)
    x = graph.mlp(x, mlp, policy.name)
    model = graph.model(x, contract)
    content = model.SerializeToString()
    _check_parity(content, policy, task_id, actor)
    return write_atomic(out, content)


def export_onnx(module: Any, task_id: str, out: str | Path, **options: Any) -> Path:
    """Export a torch actor to the ONNX file `out`, written atomically: `onnx_bytes`."""
    return write_atomic(out, onnx_bytes(module, task_id, **options))


def onnx_bytes(
    module: Any,
    task_id: str,
    *,
    action_mode: str | None = None,
    mean: np.ndarray | None = None,
    std: np.ndarray | None = None,
    clip: float | None = None,
    algorithm: str = "ONNX policy",
    training_steps: int | None = None,
    training_seed: int | None = None,
    opset: int | None = None,
    dynamo: bool = False,
    state_width: int | None = None,
    mask: np.ndarray | None = None,
    group: str | None = None,
) -> bytes:
    """The ONNX file of a torch actor that maps raw (or normalized) observations of
    `task_id`'s bots to its action scores (Discrete: one per action) or its action (Box),
    with its contract, read back by bbbench's reader.

    `mean`, `std` and `clip`: a normalizer the actor was trained behind, `clip((obs -
    mean) / std, -clip, clip)` (CleanRL's and gymnasium's NormalizeObservation keep
    `mean` and `var`: std = sqrt(var + epsilon)); it is put inside the graph, computed in
    float64. `dynamo`: torch's newer exporter (`torch.onnx.export(dynamo=True)`). `opset`:
    default 17 (18 with dynamo, its lowest). `state_width`: a recurrent actor, whose
    `forward(obs, state)` gives `(scores, next_state)`, each state (batch, state_width):
    the file carries it (`bbbench.recurrent_state`) and bbbench's play loops hand each bot
    its own state back. `mask`: each observation value multiplied by it first (0 where
    the policy hears nothing: a training with the messages muted hears none in any env).
    `group`: on a mixed team's task, the robot whose bots the actor plays (its spaces; a
    team file holds one such file per group, `bbbench.policies.onnx.team`).
    """
    import torch  # lazy: torch, for exporting only

    task = spec(task_id)
    mode = action_mode or task.default_action_mode
    if task.mixed or group is not None:
        groups = group_spaces(task_id)
        if group not in groups:
            raise ValueError(
                f"{task_id}'s robot groups are {', '.join(groups)}: give group= one of them"
            )
        observation_space, action_space = groups[group]
    else:
        observation_space, action_space = agent_spaces(task_id, mode)
    contract = Contract(
        observation=observation_space.shape[0],
        action_space=action_space,
        algorithm=algorithm,
        training_steps=training_steps,
        task=task_id,
        training_seed=training_seed,
        state=state_width,
    )
    wrapped = _Normalized(module, mean, std, clip, mask).eval()
    example = (torch.zeros((2, contract.observation), dtype=torch.float32),)
    names = [INPUT], [OUTPUT]
    if state_width is not None:
        example += (torch.zeros((2, state_width), dtype=torch.float32),)
        names = [INPUT, STATE_INPUT], [OUTPUT, STATE_OUTPUT]
    with tempfile.TemporaryDirectory() as folder:
        raw = Path(folder) / "policy.onnx"
        keywords: dict[str, Any] = {"input_names": names[0], "output_names": names[1]}
        if dynamo:
            batch = torch.export.Dim("batch", min=1, max=4096)
            keywords["dynamic_shapes"] = {"obs": {0: batch}}
            if state_width is not None:
                keywords["dynamic_shapes"]["state"] = {0: batch}
            keywords["verbose"] = False
        else:
            keywords["dynamic_axes"] = {name: {0: "batch"} for name in (*names[0], *names[1])}
        with torch.no_grad(), warnings.catch_warnings():
            # torch's note that a GRU without its initial state as an input keeps the
            # batch it was exported with: a recurrent actor's state is an input.
            warnings.filterwarnings("ignore", "Exporting a model to ONNX with a batch_size")
            torch.onnx.export(
                wrapped,
                example,
                str(raw),
                opset_version=opset or (18 if dynamo else OPSET),
                dynamo=dynamo,
                external_data=False,
                **keywords,
            )
        content = raw.read_bytes()
    return _with_contract(parse_proto(content, "torch's export"), contract, "torch's export")


def export_foreign(
    source: str | Path,
    out: str | Path,
    *,
    observation: int | None = None,
    action_space: str | None = None,
    algorithm: str | None = None,
    training_steps: int | None = None,
    task: str | None = None,
    output: str | None = None,
) -> Path:
    """Give an ONNX file written by another library the contract (from its metadata, or
    `observation` and `action_space`), keeping the one output that acts (`output`: its
    name; default: the first) and what computes it, and dropping inputs nothing uses
    (RLlib's `state_ins`, and its `state_outs`)."""
    source = Path(source)
    model = parse_proto(read_file(source, MAX_FILE_BYTES, "an ONNX model (.onnx)"), str(source))
    check_safety(model, str(source))  # refused as `bbbench eval` refuses it, used or not
    props = {p.key: p.value for p in model.metadata_props}
    given = read_contract(source.name, props, observation, action_space)
    contract = dataclasses.replace(
        given,
        algorithm=algorithm or given.algorithm,
        training_steps=given.training_steps if training_steps is None else training_steps,
        task=task or given.task,
        source="metadata",
    )
    graph = model.graph
    names = [o.name for o in graph.output]
    keep = output or (names[0] if names else None)
    if keep not in names:
        raise PolicyError(f"{source}: no output {keep!r}; its outputs are {names}")
    needed, nodes = {keep}, []
    for node in reversed(graph.node):
        if any(name in needed for name in node.output):
            nodes.append(node)
            needed.update(name for name in node.input if name)
    del graph.node[:]
    graph.node.extend(reversed(nodes))
    for field, keep_it in (
        (graph.output, lambda value: value.name == keep),
        (graph.input, lambda value: value.name in needed),
        (graph.initializer, lambda value: value.name in needed),
    ):
        kept = [value for value in field if keep_it(value)]
        del field[:]
        field.extend(kept)
    return write_atomic(out, _with_contract(model, contract, str(source)))


def _with_contract(model, contract: Contract, where: str) -> bytes:
    """The `ModelProto`'s bytes with the contract in its metadata_props, checked by
    bbbench's reader (`where`: what the graph came from, named in its errors)."""
    import onnx  # lazy: onnx, for ONNX files only

    kept = [p for p in model.metadata_props if not p.key.startswith("bbbench.")]
    del model.metadata_props[:]
    model.metadata_props.extend(kept)
    onnx.helper.set_model_props(model, {**{p.key: p.value for p in kept}, **contract.metadata()})
    content = model.SerializeToString()
    _read_back(content, where)
    return content


def _read_back(content: bytes, where: str = "the exported graph") -> OnnxPolicy:
    """The exported bytes as bbbench's reader takes a file: every check, then the actor."""
    return OnnxPolicy(parse_onnx(content, where, "exported.onnx"))


def _check_parity(content: bytes, policy: Policy, task_id: str, actor) -> None:
    """The exported graph acts as the zip does, bit for bit, on observations spread over the
    task's bounds (and beyond the normalization's clip): the same actions, and for a
    Discrete policy the same scores."""
    exported = _read_back(content).actor(task_id)
    observation_space, _ = agent_spaces(task_id, policy.action_mode, policy.height_scan)
    rng = np.random.default_rng(0)
    low = np.maximum(observation_space.low, -50.0)
    high = np.minimum(observation_space.high, 50.0)
    observations = rng.uniform(low, high, (_CHECK_ROWS, len(low))).astype(np.float32)
    pairs = list(zip(exported(observations), actor(observations), strict=True))
    if isinstance(policy.action_space, spaces.Discrete):
        mlp = actor.actor if isinstance(actor, NormalizedActor) else actor
        seen = actor.normalization(observations) if mlp is not actor else observations
        pairs.append((exported.program(observations), mlp.outputs(seen)))
    for a, b in pairs:
        if np.asarray(a).tobytes() != np.asarray(b).tobytes():
            raise PolicyError(
                f"{policy.name}: the exported graph computes otherwise than the zip; please "
                f"report it"
            )


class _Graph:
    """An ONNX graph built node by node."""

    def __init__(self) -> None:
        self.nodes: list = []
        self.initializers: list = []
        self.count = 0

    def _name(self, stem: str) -> str:
        self.count += 1
        return f"{stem}_{self.count}"

    def constant(self, stem: str, value: np.ndarray) -> str:
        import onnx  # lazy: onnx, for ONNX files only

        name = self._name(stem)
        self.initializers.append(onnx.numpy_helper.from_array(np.asarray(value), name))
        return name

    def node(self, op: str, inputs: list[str], **attributes: Any) -> str:
        import onnx  # lazy: onnx, for ONNX files only

        output = self._name(op.lower())
        self.nodes.append(onnx.helper.make_node(op, inputs, [output], **attributes))
        return output

    def normalization(self, x: str, normalization) -> str:
        """VecNormalize's `clip((obs - mean) / std, -clip, clip)` in float64, to float32."""
        x = self.node("Cast", [x], to=11)
        x = self.node("Sub", [x, self.constant("mean", normalization.mean.astype(np.float64))])
        x = self.node("Div", [x, self.constant("std", normalization.std.astype(np.float64))])
        bounds = (np.float64(-normalization.clip), np.float64(normalization.clip))
        x = self.node(
            "Clip", [x, self.constant("low", bounds[0]), self.constant("high", bounds[1])]
        )
        return self.node("Cast", [x], to=1)

    def layer(self, x: str, weights: tuple[np.ndarray, np.ndarray]) -> str:
        weight_t, bias = weights
        return self.node(
            "Gemm", [x, self.constant("weight", weight_t), self.constant("bias", bias)]
        )

    def activation(self, x: str, name: str) -> str:
        if name == "SiLU":
            return self.node("Mul", [x, self.node("Sigmoid", [x])])
        op = {"Tanh": "Tanh", "ReLU": "Relu", "Sigmoid": "Sigmoid", "ELU": "Elu"}.get(name)
        if name == "LeakyReLU":
            return self.node("LeakyRelu", [x], alpha=0.01)
        return self.node(op, [x])

    def mlp(self, x: str, mlp, name: str) -> str:
        """`MlpActor`'s network and its deterministic output (argmax's scores; a Box's mean,
        or its tanh scaled to the bounds)."""
        if mlp.quantiles > 1:
            raise PolicyError(
                f"{name}: QR-DQN's mean over quantiles is not exported (numpy's float32 mean "
                f"could not be matched bit for bit); score the zip"
            )
        for weights in mlp.hidden:
            x = self.activation(self.layer(x, weights), mlp.activation)
        x = self.layer(x, mlp.head)
        if mlp.output in ("squashed_gaussian", "tanh"):
            if mlp.mean_clip is not None:
                bound = np.float32(mlp.mean_clip)
                x = self.node(
                    "Clip", [x, self.constant("low", -bound), self.constant("high", bound)]
                )
            x = self.node("Tanh", [x])  # low + 0.5 (tanh + 1) (high - low), as MlpActor
            x = self.node("Add", [x, self.constant("one", np.float32(1.0))])
            x = self.node("Mul", [self.constant("half", np.float32(0.5)), x])
            x = self.node(
                "Mul", [x, self.constant("range", (mlp.high - mlp.low).astype(np.float32))]
            )
            x = self.node("Add", [self.constant("low", mlp.low.astype(np.float32)), x])
        return x

    def model(self, x: str, contract: Contract):
        import onnx  # lazy: onnx, for ONNX files only

        x = self.node("Identity", [x])
        self.nodes[-1].output[0] = OUTPUT
        space = contract.action_space
        width = int(space.n if isinstance(space, spaces.Discrete) else space.shape[0])
        graph = onnx.helper.make_graph(
            self.nodes,
            "bbbench_policy",
            [
                onnx.helper.make_tensor_value_info(
                    INPUT, onnx.TensorProto.FLOAT, ["batch", contract.observation]
                )
            ],
            [onnx.helper.make_tensor_value_info(OUTPUT, onnx.TensorProto.FLOAT, ["batch", width])],
            self.initializers,
        )
        model = onnx.helper.make_model(
            graph,
            producer_name="bbbench",
            opset_imports=[onnx.helper.make_opsetid("", OPSET)],
            ir_version=IR_VERSION,
        )
        onnx.helper.set_model_props(model, contract.metadata())
        model.doc_string = (
            f"A bbbench policy: {contract.observation} observation values -> "
            f"{describe_action_space(contract.action_space)}"
        )
        return model


class _Normalized:
    """Built lazily as a torch module (torch is imported only to export)."""

    def __new__(cls, module, mean, std, clip, mask=None):
        import torch  # lazy: torch, for exporting only

        class Normalized(torch.nn.Module):
            def __init__(self) -> None:
                super().__init__()
                self.module = module
                self.normalize = mean is not None
                self.masked = mask is not None
                if self.masked:
                    self.register_buffer("mask", torch.as_tensor(np.asarray(mask, np.float32)))
                if self.normalize:
                    self.register_buffer("mean", torch.as_tensor(np.asarray(mean, np.float64)))
                    self.register_buffer("std", torch.as_tensor(np.asarray(std, np.float64)))
                    self.clip = None if clip is None else float(clip)

            def forward(self, obs, *state):
                if self.masked:
                    obs = obs * self.mask
                if self.normalize:
                    scaled = (obs.double() - self.mean) / self.std
                    if self.clip is not None:
                        scaled = scaled.clamp(-self.clip, self.clip)
                    obs = scaled.float()
                return self.module(obs, *state)

        if (mean is None) != (std is None):
            raise ValueError("give both mean and std for a normalizer, or neither")
        return Normalized()

"""An ONNX model as a `Policy`: read safely, run by bbbench's interpreter.

The model is read without trusting it (`bbbench.policies.onnx.reader`), its
contract taken from its metadata or the command line
(`bbbench.policies.onnx.contract`), and its graph compiled to a `Program` on
portable arithmetic (`bbbench.policies.onnx.interpreter`), then tried once on a
trial batch: every shape, type and the output's width are checked before an
episode is played. onnxruntime never scores: its kernels round by CPU.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from bbbench.policies.errors import PolicyError
from bbbench.policies.file_policy import FilePolicy
from bbbench.policies.onnx.contract import STATE, Contract, read_contract
from bbbench.policies.onnx.interpreter import Program, compile_graph, compile_steps, trial_shapes
from bbbench.policies.onnx.reader import OnnxModel, read_onnx
from bbbench.policies.policy import Actor
from bbbench.tasks.suite import agent_layout, spec

_TRIAL_ROWS = 3


class OnnxPolicy(FilePolicy):
    """An ONNX policy file. `observation` and `action_space`: its contract, given on the
    command line for a file whose metadata carries none."""

    deterministic_only = "its graph gives no sampling distribution"

    def __init__(
        self,
        path: str | Path | OnnxModel,
        observation: int | None = None,
        action_space: str | None = None,
    ) -> None:
        model = path if isinstance(path, OnnxModel) else read_onnx(path)
        self.contract = contract = read_contract(
            model.name, model.metadata, observation, action_space
        )
        self.name = model.name
        self.sha256 = model.sha256
        self.algorithm = contract.algorithm
        self.training_steps = contract.training_steps
        self.training_seed = contract.training_seed
        self.observation_shape = contract.observation_shape
        self.action_space = contract.action_space
        self.action_mode = (
            "discrete" if isinstance(self.action_space, spaces.Discrete) else "continuous"
        )
        self._set_layout()
        # A mixed team's group policy names its team's task: the team file checks its fit.
        trained_on = None if contract.task is None or spec(contract.task).mixed else contract.task
        if trained_on is not None and self.mismatch(trained_on) is not None:
            raise PolicyError(
                f"{self.name}: its metadata says it was trained on {contract.task}, which it "
                f"cannot play ({self.spaces_text()}): {self.mismatch(contract.task)}"
            )
        self._actor = _actor(model, contract)

    def mismatch(self, task_id: str) -> str | None:
        """Its spaces' reason (`FilePolicy`); and for a file whose contract names the task
        it was trained on, a task whose observation means other things (the same width, other
        fields: Swap-v0's goal against ConvoyTurns-v0's tethers)."""
        reason = super().mismatch(task_id)
        trained_on = self.contract.task
        if reason is not None or trained_on is None:
            return reason
        ours = agent_layout(trained_on, self.height_scan)
        theirs = agent_layout(task_id, self.height_scan)
        if ours == theirs:
            return None
        value, mine, other = next(
            (k, a, b) for k, (a, b) in enumerate(zip(ours, theirs, strict=True)) if a != b
        )
        return (
            f"its metadata says it was trained on {trained_on}, whose observation means other "
            f"things than {task_id}'s (value {value} is {mine!r} there, {other!r} here)"
        )

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        return self._actor

    def record(self) -> dict[str, Any]:
        record = super().record()
        record["format"] = "onnx"
        record["contract"] = self.contract.record()
        return record


@dataclasses.dataclass(frozen=True, eq=False)
class OnnxActor:
    """A compiled graph acting: Discrete, the best score (None where a row is NaN); Box, the
    output clipped to the bounds. `rows`: the graph takes one observation a call."""

    program: Program
    discrete: bool
    greedy: bool  # the graph ends in its chain of layers: the chain's own greedy actions
    rows: bool
    low: np.ndarray | None = None
    high: np.ndarray | None = None

    def __call__(self, observations: np.ndarray, rngs=None) -> list:
        observations = np.asarray(observations, dtype=np.float32)
        if self.greedy and not self.rows:
            return self.program.greedy_mlp(observations)
        if self.rows:
            if self.greedy:
                return [self.program.greedy_mlp(row[None])[0] for row in observations]
            out = np.concatenate([self.program(row[None]) for row in observations])
        else:
            out = self.program(observations)
        return _actions(out, self.discrete, self.low, self.high)


def _actions(out: np.ndarray, discrete: bool, low, high) -> list:
    """A graph's outputs as actions: Discrete, the best score; Box, the output clipped to
    the bounds; None for a row with NaN."""
    broken = np.isnan(out).any(axis=1)
    if discrete:
        actions = out.argmax(axis=1).tolist()
    else:
        actions = list(np.clip(out, low, high).astype(np.float32))
    return [None if nan else action for action, nan in zip(actions, broken, strict=True)]


@dataclasses.dataclass(frozen=True, eq=False)
class RecurrentOnnxActor:
    """A recurrent graph acting (`bbbench.recurrent_state`): `step` takes each row's state
    and gives its next one with the actions; the play loops
    (`bbbench.evaluation.play`) start every bot at `initial_state` and hand each its own
    state back at every step."""

    program: Program
    discrete: bool
    rows: bool  # the graph takes one observation a call
    state_width: int
    low: np.ndarray | None = None
    high: np.ndarray | None = None

    def initial_state(self, rows: int) -> np.ndarray:
        """Every row's state at the start of its episode: zeros."""
        return np.zeros((rows, self.state_width), dtype=np.float32)

    def step(
        self, observations: np.ndarray, states: np.ndarray, rngs=None
    ) -> tuple[list, np.ndarray]:
        """The actions for a batch of observations from each row's state, and the next
        states."""
        observations = np.asarray(observations, dtype=np.float32)
        if self.rows:
            parts = [
                self.program.step(o[None], h[None])
                for o, h in zip(observations, states, strict=True)
            ]
            out = np.concatenate([part[0] for part in parts])
            states = np.concatenate([part[1] for part in parts])
        else:
            out, states = self.program.step(observations, states)
        return _actions(out, self.discrete, self.low, self.high), states

    def __call__(self, observations: np.ndarray, rngs=None) -> list:
        raise PolicyError(
            "a recurrent ONNX policy acts with its state: it plays through bbbench's play "
            "loops (bbbench eval, the board), which carry each bot's state from step to step"
        )


def _actor(model, contract: Contract) -> OnnxActor:
    """The model's actor, after trial runs that check what the episodes will need."""
    where, width = model.name, contract.observation
    if model.input_width is not None and model.input_width != width:
        raise PolicyError(
            f"{where}: its input {model.input!r} is {model.input_width} wide, but its contract "
            f"says the observation is {width} ({contract.source})"
        )
    space = contract.action_space
    discrete = isinstance(space, spaces.Discrete)
    outputs = int(space.n if discrete else space.shape[0])
    if model.output_width is not None and model.output_width != outputs:
        raise PolicyError(
            f"{where}: its output {model.output!r} is {model.output_width} wide, but its "
            f"contract's {space} needs {outputs}"
        )
    state = _state_width(model, contract)
    trial = np.linspace(-1.0, 1.0, _TRIAL_ROWS * width, dtype=np.float32).reshape(
        _TRIAL_ROWS, width
    )
    compiled = compile_steps(model)
    shapes = _trial(compiled, trial[:1], outputs, state)
    rows = not model.batched
    if not rows:  # batched: one call must give what row-by-row calls give
        try:
            shapes = _trial(compiled, trial, outputs, state)
        except PolicyError:
            rows = True
    program = compile_graph(compiled, discrete, shapes)
    low, high = (None, None) if discrete else (space.low.copy(), space.high.copy())
    rows = rows or not _rows_agree(program, trial, state)
    if state is not None:
        return RecurrentOnnxActor(program, discrete, rows, state, low, high)
    greedy = discrete and program.mlp is not None and program.output == program.mlp_output
    return OnnxActor(program, discrete, greedy, rows, low=low, high=high)


def _rows_agree(program, trial: np.ndarray, state: int | None) -> bool:
    """Whether one batched call gives, bit for bit, what row-by-row calls give (else the
    actor calls the graph a row at a time: the same bits for any batch); a recurrent
    graph's next states too, from states other than zeros."""
    if state is None:
        together = program(trial)
        apart = np.concatenate([program(row[None]) for row in trial])
    else:
        held = np.linspace(-0.5, 0.5, len(trial) * state, dtype=np.float32)
        held = held.reshape(len(trial), state)
        together = np.concatenate(program.step(trial, held), axis=1)
        apart = np.concatenate(
            [
                np.concatenate(program.step(o[None], h[None]), axis=1)
                for o, h in zip(trial, held, strict=True)
            ]
        )
    return np.array_equal(together.view(np.uint32), apart.view(np.uint32))


def _state_width(model, contract: Contract) -> int | None:
    """The recurrent state's width, where the contract and the graph agree on one;
    `PolicyError` where one has a state and the other none, or their widths differ."""
    where, state = model.name, contract.state
    if state is None and model.state_input is not None:
        raise PolicyError(
            f"{where}: its graph takes a state ({model.state_input!r} in, "
            f"{model.state_output!r} out), but its contract names no {STATE} width; export "
            f"it with its state width (bbbench.policies.onnx.export.onnx_bytes(state_width=N))"
        )
    if state is not None and model.state_input is None:
        raise PolicyError(
            f"{where}: its contract says it carries a state of {state} ({STATE}), but its "
            f"graph has no state input and output: a recurrent policy takes (observation, "
            f"state) and gives (action, next state)"
        )
    if state is not None and model.state_width not in (None, state):
        raise PolicyError(
            f"{where}: its state input {model.state_input!r} is {model.state_width} wide, but "
            f"its contract says {state} ({STATE})"
        )
    return state


def _trial(compiled, observations: np.ndarray, outputs: int, state: int | None = None):
    model = compiled.model
    rows = len(observations)
    states = None if state is None else np.zeros((rows, state), dtype=np.float32)
    shapes = trial_shapes(compiled, observations, states)
    got = shapes[model.output]
    want = (rows, outputs)
    if got != want:
        raise PolicyError(
            f"{model.name}: on a batch of {want[0]} observation(s) its output has shape "
            f"{got}, not {want}: the output disagrees with the contract (one score per action "
            f"for Discrete, the action for Box)"
        )
    if state is not None and shapes[model.state_output] != (rows, state):
        raise PolicyError(
            f"{model.name}: on a batch of {rows} observation(s) its state output "
            f"{model.state_output!r} has shape {shapes[model.state_output]}, not {(rows, state)} "
            f"(the state it takes, {STATE})"
        )
    return shapes

"""What an ONNX policy promises: the observation it reads and the actions it writes.

An ONNX graph says nothing of what its numbers mean. bbbench reads the contract
from the model's `metadata_props`, inside the file, so that the one SHA-256 the
board records covers it:

- `bbbench.observation`: the observation width: 5 (the two-wheel bot), 16 (with
  the height scan), 17 (the multi-bot layout, or the wheel-legged robot's), 19
  (the team tasks), 28 (the wheel-legged robot with the height scan);
- `bbbench.action_space`: the action space as Gymnasium prints it:
  `Discrete(9)`, `Box(-1.0, 1.0, (1,), float32)`;
- optional, for the board: `bbbench.algorithm` (what trained it, e.g. `PPO`),
  `bbbench.training_steps` (world steps, the board's unit: a multi-bot world step
  moves every bot once; files `bbbench train` wrote for IPPO and MAPPO before issue 65
  counted bot-steps here),
  `bbbench.task` (the task it was trained on) and `bbbench.training_seed` (the
  training's seed: marl-eval's run name, `run_<seed>`);
- `bbbench.recurrent_state`, for a policy that carries a state from step to step (a
  GRU's): the state's width N. Its graph then takes two inputs, the observation and the
  state (batch, N), and gives two outputs, the action scores (or action) and the next
  state (batch, N). Each bot starts its episode from zeros, and the play loops hand each
  bot its own state back at every step.

The graph's input is the raw bbbench observation (any normalization is inside
the graph). A Discrete policy outputs one score per action and plays the best;
a Box policy outputs the action, which is clipped to the bounds.

A file without the contract is scored with it given on the command line
(`--observation N --action-space SPACE`); the results record where it came from.
"""

from __future__ import annotations

import ast
import dataclasses
import re
from typing import Any

import numpy as np
from gymnasium import spaces

from bbbench.policies.errors import NoContract, PolicyError
from bbbench.tasks.suite import spec

PREFIX = "bbbench."
OBSERVATION, ACTION_SPACE = "bbbench.observation", "bbbench.action_space"
ALGORITHM, TRAINING_STEPS, TASK = "bbbench.algorithm", "bbbench.training_steps", "bbbench.task"
TRAINING_SEED = "bbbench.training_seed"
STATE = "bbbench.recurrent_state"
KEYS = (OBSERVATION, ACTION_SPACE, ALGORITHM, TRAINING_STEPS, TASK, TRAINING_SEED, STATE)
MAX_STATE = 4096  # a recurrent state's values per bot: far beyond a policy's GRU
MAX_OBSERVATION = 1024  # wider than any layout of the suite
MAX_ACTIONS = 64  # a Box's values
# A Discrete space's actions: the largest of the suite is the steering robot's 27 times a
# channel's 3 ** 4 messages (`bbbench.tasks.channel.MAX_WIDTH`), 2,187.
MAX_DISCRETE = 4096
MAX_TRAINING_STEPS = 10**13  # far beyond any training; the board shows the count as given
MAX_SEED = 2**63 - 1
FLAGS = "--observation N (the observation width: 5, 16, 17, 19 ...) and --action-space SPACE"

_DISCRETE = re.compile(r"Discrete\((\d+)\)")
# Gymnasium's repr of a Box: Box(low, high, shape, dtype); low and high a number or a
# numpy array's print ("[-1. -1.]").
# The dtype may be left out (float32), as bbbench's errors and README print a Box.
_BOX = re.compile(
    r"Box\((?P<low>.+?), (?P<high>.+?), \((?P<shape>[\d, ]*)\)(?:, (?P<dtype>\w+))?\)"
)


@dataclasses.dataclass(frozen=True)
class Contract:
    """The spaces an ONNX policy works in, and what the board shows of its training."""

    observation: int
    action_space: spaces.Discrete | spaces.Box
    algorithm: str = "ONNX policy"
    training_steps: int | None = None
    task: str | None = None
    training_seed: int | None = None
    source: str = "metadata"  # where it came from: "metadata" or "command line"
    state: int | None = None  # a recurrent policy's state width (`bbbench.recurrent_state`)

    @property
    def observation_shape(self) -> tuple[int]:
        return (self.observation,)

    def metadata(self) -> dict[str, str]:
        """The contract as `metadata_props`."""
        props = {
            OBSERVATION: str(self.observation),
            ACTION_SPACE: describe_action_space(self.action_space),
            ALGORITHM: self.algorithm,
        }
        if self.training_steps is not None:
            props[TRAINING_STEPS] = str(self.training_steps)
        if self.task is not None:
            props[TASK] = self.task
        if self.training_seed is not None:
            props[TRAINING_SEED] = str(self.training_seed)
        if self.state is not None:
            props[STATE] = str(self.state)
        return props

    def record(self) -> dict[str, Any]:
        """As the results document records it."""
        record = {
            "observation": self.observation,
            "action_space": describe_action_space(self.action_space),
            "from": self.source,
        }
        if self.state is not None:
            record["recurrent_state"] = self.state
        return record


def describe_action_space(space: spaces.Space) -> str:
    """Gymnasium's own print of a Discrete or float32 Box space."""
    return str(space)


def parse_action_space(text: str, where: str) -> spaces.Discrete | spaces.Box:
    """A Discrete or float32 Box space from its Gymnasium print; `PolicyError` else."""
    example = "e.g. 'Discrete(9)' or 'Box(-1.0, 1.0, (1,), float32)'"
    text = text.strip()
    match = _DISCRETE.fullmatch(text)
    if match:
        n = int(match.group(1))
        if not 1 <= n <= MAX_DISCRETE:
            raise PolicyError(f"{where}: {text}: 1 to {MAX_DISCRETE} actions")
        return spaces.Discrete(n)
    match = _BOX.fullmatch(text)
    if match is None:
        raise PolicyError(
            f"{where}: {text!r} is not an action space as Gymnasium prints it ({example})"
        )
    if match["dtype"] not in (None, "float32"):
        raise PolicyError(f"{where}: {text}: bbbench's Box actions are float32")
    try:
        shape = tuple(int(n) for n in match["shape"].replace(" ", "").split(",") if n)
        if len(shape) != 1 or not 1 <= shape[0] <= MAX_ACTIONS:
            raise ValueError("one dimension of 1 to 64 actions")
        low, high = (_bound(match[name], shape) for name in ("low", "high"))
        return spaces.Box(low, high, shape, np.float32)
    except (ValueError, SyntaxError) as error:
        raise PolicyError(f"{where}: {text}: {error} ({example})") from None


def _bound(text: str, shape: tuple[int]) -> np.ndarray:
    text = text.strip()
    if text.startswith("["):  # numpy's print of an array: "[-1. -1.]"
        values = [float(v) for v in text.strip("[]").split()]
    else:
        values = [float(ast.literal_eval(text))] * shape[0]
    if len(values) != shape[0] or not np.isfinite(values).all():
        raise ValueError(f"bounds {text} for shape {shape}")
    return np.array(values, dtype=np.float32)


def read_contract(
    where: str,
    props: dict[str, str],
    observation: int | None = None,
    action_space: str | None = None,
) -> Contract:
    """The contract from a model's `metadata_props`, or else from the command line
    (`observation`, `action_space`); `PolicyError` if neither gives it, or they disagree."""
    unknown = sorted(key for key in props if key.startswith(PREFIX) and key not in KEYS)
    if unknown:
        raise PolicyError(f"{where}: unknown metadata key(s) {unknown}; bbbench reads {list(KEYS)}")
    given = observation is not None or action_space is not None
    if OBSERVATION not in props and ACTION_SPACE not in props:
        if observation is None or action_space is None:
            raise NoContract(
                f"{where}: its metadata_props carry no bbbench contract: give {FLAGS} (as "
                f"Gymnasium prints it, e.g. 'Discrete(9)'), or export it with bbbench export",
                where,
            )
        return Contract(
            observation=_width(observation, "--observation"),
            action_space=parse_action_space(action_space, "--action-space"),
            source="command line",
        )
    for key in (OBSERVATION, ACTION_SPACE):
        if key not in props:
            raise PolicyError(f"{where}: metadata_props has no {key!r} (a contract needs both)")
    try:
        width = int(props[OBSERVATION])
    except ValueError:
        raise PolicyError(
            f"{where}: {OBSERVATION} must be an integer, got {props[OBSERVATION]!r}"
        ) from None
    contract = Contract(
        observation=_width(width, f"{where}: {OBSERVATION}"),
        action_space=parse_action_space(props[ACTION_SPACE], f"{where}: {ACTION_SPACE}"),
        algorithm=props.get(ALGORITHM, "ONNX policy").strip()[:60] or "ONNX policy",
        training_steps=_whole(where, TRAINING_STEPS, props.get(TRAINING_STEPS), MAX_TRAINING_STEPS),
        task=_task(where, props.get(TASK)),
        training_seed=_whole(where, TRAINING_SEED, props.get(TRAINING_SEED), MAX_SEED),
        state=_whole(where, STATE, props.get(STATE), MAX_STATE),
    )
    if contract.state == 0:
        raise PolicyError(f"{where}: {STATE} must be a whole number from 1 to {MAX_STATE:,}, got 0")
    if given:
        on_command_line = (observation, action_space)
        in_file = (contract.observation, describe_action_space(contract.action_space))
        if (observation is not None and observation != contract.observation) or (
            action_space is not None
            and parse_action_space(action_space, "--action-space") != contract.action_space
        ):
            raise PolicyError(
                f"{where}: the command line's contract {on_command_line} disagrees with the "
                f"file's {in_file}; drop --observation and --action-space"
            )
    return contract


def _width(value: int, what: str) -> int:
    if not 1 <= value <= MAX_OBSERVATION:
        raise PolicyError(f"{what}: {value} is not an observation width (1 to {MAX_OBSERVATION})")
    return value


def _whole(where: str, key: str, text: str | None, most: int) -> int | None:
    if text is None:
        return None
    try:
        value = int(text) if len(text) <= 32 else -1
    except ValueError:
        value = -1
    if not 0 <= value <= most:
        shown = text if len(text) <= 32 else f"{text[:29]}..."
        raise PolicyError(
            f"{where}: {key} must be a whole number from 0 to {most:,}, got {shown!r}"
        )
    return value


def _task(where: str, task_id: str | None) -> str | None:
    """The task the metadata names: one of the suite's IDs, or `PolicyError`."""
    if task_id is None:
        return None
    try:
        return spec(task_id).id
    except ValueError as error:
        raise PolicyError(f"{where}: {TASK} {task_id[:80]!r}: {error}") from None

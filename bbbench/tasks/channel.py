"""`Channel`: the bots of a multi-bot task talk, as VMAS's agents do (`dim_c`).

A task that enables a channel (`TaskSpec.channel`) gives each bot `width` message
values beside its robot's action, and each bot observes the messages of the `slots`
nearest other bots within `range` m, beside where they are, in a block of slots like
the neighbour block (`message_layout`):

    sender{k}_right, sender{k}_forward   where the k-th nearest sender is, in this bot's frame
    sender{k}_message{j}                 its j-th message value, in [-1, 1]
    sender{k}_present                    1 for a sender, 0 for an empty slot (all zeros)

A message arrives one step later: what a bot sends with the action of step t is read in
the observations that step returns, the input of the actions of step t + 1 (VMAS's
`state.c`); after a reset every message reads 0. A bot that has left the episode sends
nothing.

The action grows by the message values:

- `discrete`: the robot's n actions times 3 ** width messages (`LEVELS` per value):
  index = robot action x 3 ** width + message code, the code's base-3 digits, most
  significant first, each picking -1, 0 or 1 (VMAS flattens its discrete communication
  into one `Discrete` in the same way);
- `continuous`: a `Box` of the robot's values, then `width` values in [-1, 1].

`muted=True` zeroes every message a bot reads (not where its sender is): the ablation
that shows what the channel carries.
"""

from __future__ import annotations

import operator
import re
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numpy as np
from gymnasium import spaces

from bbbench.parameters import parameters
from bbbench.robots.layout import ObservationField
from bbbench.tasks.group import MAX_BOTS, nearest_others

LEVELS = (-1.0, 0.0, 1.0)  # the values a discrete action's message value takes
MAX_WIDTH = 4  # message values per bot: 3 ** 4 x 27 = 2,187 discrete actions at most
MAX_RANGE = 20.0  # m: beyond every world's size
# The observation's message values, by name (`Channel.layout`): what muting zeroes.
MESSAGE_FIELD = re.compile(r"sender\d+_message\d+")


@parameters
class Channel:
    """What the bots of a multi-bot task can say (module docstring): `width` message
    values each (1 to `MAX_WIDTH`), heard by the `slots` nearest other bots within
    `range` m (0 to `MAX_RANGE`); `muted` reads every message as 0."""

    width: int = 2
    range: float = 6.0  # m
    slots: int = 3
    muted: bool = False

    def __post_init__(self) -> None:
        width = _whole(self.width)
        if width is None or not 1 <= width <= MAX_WIDTH:
            raise ValueError(
                f"message_width must be a whole number from 1 to {MAX_WIDTH}, got {self.width!r}"
            )
        if not (
            isinstance(self.range, int | float)
            and not isinstance(self.range, bool)
            and 0.0 < self.range <= MAX_RANGE
        ):
            raise ValueError(
                f"comm_range must be a distance in (0, {MAX_RANGE:g}] m, got {self.range!r}"
            )
        slots = _whole(self.slots)
        if slots is None or not 1 <= slots < MAX_BOTS:
            raise ValueError(
                f"slots must be a whole number from 1 to {MAX_BOTS - 1}, got {self.slots!r}"
            )
        if self.muted is not True and self.muted is not False:
            raise ValueError(f"mute_messages must be True or False, got {self.muted!r}")

    @property
    def codes(self) -> int:
        """How many messages a discrete action can send: 3 ** width."""
        return len(LEVELS) ** self.width

    def action_space(self, robot_space: spaces.Space) -> spaces.Space:
        """The robot's action space grown by the message values (module docstring)."""
        if isinstance(robot_space, spaces.Discrete):
            return spaces.Discrete(int(robot_space.n) * self.codes)
        ones = np.ones(self.width, dtype=robot_space.dtype)
        return spaces.Box(
            np.concatenate([robot_space.low, -ones]),
            np.concatenate([robot_space.high, ones]),
            dtype=robot_space.dtype,
        )

    def splitter(self, robot_space: spaces.Space) -> Callable[[Any], tuple[Any, tuple]]:
        """The function from an action of `action_space(robot_space)` to the robot's
        action and the message (a tuple of `width` floats), or a ValueError that says
        what was expected."""
        width, codes = self.width, self.codes
        if isinstance(robot_space, spaces.Discrete):
            n = int(robot_space.n)
            messages = [_digits(code, width) for code in range(codes)]

            def split_discrete(action: Any) -> tuple[Any, tuple]:
                index = _whole(action)
                if index is None or not 0 <= index < n * codes:
                    raise ValueError(
                        f"discrete action {action!r} is not in the action space: expected an "
                        f"integer index 0..{n * codes - 1}, robot action x {codes} + message "
                        f"code (its {width} base-3 digits pick {LEVELS})"
                    )
                return index // codes, messages[index % codes]

            return split_discrete
        size = robot_space.shape[0]

        def split_continuous(action: Any) -> tuple[Any, tuple]:
            values = np.asarray(action, dtype=np.float64)
            if values.shape != (size + width,):
                raise ValueError(
                    f"continuous action {action!r} is not in the action space: expected "
                    f"{size + width} values, the robot's {size} then {width} message values "
                    f"in [-1, 1]"
                )
            message = values[size:]
            if not np.all(np.abs(message) <= 1.0):  # NaN fails too
                raise ValueError(
                    f"message values {message.tolist()} are not in [-1, 1] (the last {width} "
                    f"values of the action)"
                )
            return values[:size], tuple(float(value) for value in message)

        return split_continuous

    def layout(self) -> tuple[ObservationField, ...]:
        """The fields of the message block (module docstring)."""
        reach = self.range
        fields = []
        for k in range(1, self.slots + 1):
            fields += [
                ObservationField(f"sender{k}_right", "m", -reach, reach,
                                 f"the {k}th nearest bot that can be heard: how far to the right"),
                ObservationField(f"sender{k}_forward", "m", -reach, reach, "how far ahead"),
            ]  # fmt: skip
            fields += [
                ObservationField(f"sender{k}_message{j}", "", -1.0, 1.0,
                                 f"message value {j} it sent with its last action")
                for j in range(self.width)
            ]  # fmt: skip
            fields.append(
                ObservationField(f"sender{k}_present", "", 0.0, 1.0, "1: a sender, 0: empty")
            )
        return tuple(fields)

    def silence(self, n_bots: int) -> list[tuple[float, ...]]:
        """Every bot's message after a reset: zeros."""
        return [(0.0,) * self.width] * n_bots

    def blocks(
        self,
        states: list[Any],
        sent: list[tuple[float, ...]],
        nearest: list[list[int]] | None = None,
        positions: list[complex] | None = None,
    ) -> list[list[float]]:
        """The live bots' message blocks, one list of values each: from their `states`
        (in order) and the messages each `sent` with its last action (in the same
        order); `nearest`, each bot's others nearest first where the caller has them
        (`nearest_others`, at least `slots` each where there are as many), and
        `positions`, each bot's x + iy. Plain floats, as `group_observations`."""
        size = self.slots * (self.width + 3)
        silent = (0.0,) * self.width if self.muted else None
        if positions is None:
            positions = [complex(state.position[0], state.position[1]) for state in states]
        slots = self.slots
        if nearest is None:
            nearest = nearest_others(positions, slots) if len(states) > 1 else [[]]
        reach, rows = self.range, []
        for i, state in enumerate(states):
            forward_x, forward_y = state.heading
            turn = complex(forward_y, forward_x)  # world -> right + i ahead, as neighbours
            here, row = positions[i], []
            for j in nearest[i][:slots]:
                offset = (positions[j] - here) * turn
                if abs(offset) > reach:
                    break  # the rest are farther
                row += (offset.real, offset.imag, *(silent or sent[j]), 1.0)
            row += [0.0] * (size - len(row))
            rows.append(row)
        return rows


class SenderSlot(NamedTuple):
    """Where one slot of the message block sits in a bot's row: the column of its
    `sender{k}_right` (`forward` follows), of each `sender{k}_message{j}`, and of its
    `sender{k}_present`, the slot's last."""

    right: int
    messages: tuple[int, ...]
    present: int


def sender_slots(names: Sequence[str]) -> list[SenderSlot]:
    """The message block's slots, nearest sender first, in a row whose values are `names`
    (`bbbench.tasks.suite.agent_layout`); none where the row has no channel."""
    column = {name: c for c, name in enumerate(names)}
    slots, k = [], 1
    while f"sender{k}_present" in column:
        messages, j = [], 0
        while f"sender{k}_message{j}" in column:
            messages.append(column[f"sender{k}_message{j}"])
            j += 1
        slots.append(
            SenderSlot(column[f"sender{k}_right"], tuple(messages), column[f"sender{k}_present"])
        )
        k += 1
    return slots


def _whole(value: Any) -> int | None:
    if isinstance(value, bool):
        return None
    try:
        return operator.index(value)
    except TypeError:
        return None


def _digits(code: int, width: int) -> tuple[float, ...]:
    """The message of a discrete code: its base-3 digits, most significant first, as
    `LEVELS`."""
    digits = []
    for _ in range(width):
        code, digit = divmod(code, len(LEVELS))
        digits.append(LEVELS[digit])
    return tuple(reversed(digits))


def nearest_level(value: float) -> int:
    """The index in `LEVELS` of the level nearest `value` (between two, the lower): how a
    message value is read as a discrete one."""
    return min(range(len(LEVELS)), key=lambda d: abs(LEVELS[d] - value))


def code_of(message: tuple[float, ...]) -> int:
    """The discrete code of a message of `LEVELS` values (the inverse of `_digits`); a
    value between levels goes to the nearest."""
    code = 0
    for value in message:
        code = code * len(LEVELS) + nearest_level(value)
    return code

"""The rendezvous task's classical team controller: the scout says which landmark is the
goal, every bot that has heard it says it again (a relay, for bots beyond the scout's
range), and each bot that knows heads there with the steering law, past its neighbours.

A landmark is said in the first two message values, each -1 or 1 (`CODES`); a bot that
knows nothing says zeros, and stands. Messages are read from the nearest sender that
says a landmark; the scout trusts its own one-hot first.
"""

from __future__ import annotations

import numpy as np

from bbbench.policies.controllers.steer import TARGET_VELOCITY, Avoiding, SteerController
from bbbench.tasks.channel import Channel, code_of
from bbbench.tasks.scenarios.rendezvous import ARRIVAL_RATE, GATHERED, LANDMARKS

# Landmark k's message: its first two values (the rest zeros); zeros say nothing.
CODES = ((-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0))
WIDTH_NEEDED = 2  # message values the code takes


def heard(values: tuple[float, float]) -> int | None:
    """The landmark a message's first two values say, or None for one that says none (a
    value nearer 0 than +-1)."""
    first, second = values
    if abs(first) < 0.5 or abs(second) < 0.5:
        return None
    return 2 * (first > 0.0) + (second > 0.0)


class RendezvousController:
    """The team controller on one bot's observation of a rendezvous task.

    Args:
        layout: the names of the observation's values (`bbbench.tasks.suite.agent_layout`).
        channel: the task's channel (its width and slots).
        neighbours: the neighbour block's slots.
        action_mode: "discrete" or "continuous" (the steering robot's modes).
    """

    def __init__(
        self, layout: tuple[str, ...], channel: Channel, neighbours: int, action_mode: str
    ) -> None:
        if channel.width < WIDTH_NEEDED:
            raise ValueError(
                f"the rendezvous controller says a landmark in {WIDTH_NEEDED} message values; "
                f"the channel has {channel.width}"
            )
        names = list(layout)
        self.landmarks = [names.index(f"landmark{k}_distance") for k in range(LANDMARKS)]
        self.told = names.index("goal_is_landmark0")
        self.senders = [
            (names.index(f"sender{k}_message0"), names.index(f"sender{k}_present"))
            for k in range(1, channel.slots + 1)
        ]
        self.avoid = Avoiding(names.index("neighbour1_right"), neighbours, radius=1.0)
        self.width, self.codes, self.action_mode = channel.width, channel.codes, action_mode
        self.steer = SteerController(action_mode, guide=self.guide)

    def goal(self, observation: np.ndarray) -> int | None:
        """The landmark this bot knows to be the goal: told (the scout), or heard from the
        nearest sender that says one; None if neither."""
        told = observation[self.told : self.told + LANDMARKS]
        if float(told.max()) > 0.5:
            return int(told.argmax())
        for message, present in self.senders:
            if observation[present] > 0.5:
                said = heard((float(observation[message]), float(observation[message + 1])))
                if said is not None:
                    return said
        return None

    def guide(self, observation: np.ndarray) -> tuple[float, float]:
        """The (velocity, yaw rate) towards the goal, slowing to stand within `GATHERED`
        m, past the neighbours; standing when the goal is not known."""
        goal = self.goal(observation)
        if goal is None:
            return 0.0, 0.0
        at = self.landmarks[goal]
        distance, cos, sin = (float(value) for value in observation[at : at + 3])
        speed = min(
            float(observation[TARGET_VELOCITY]), ARRIVAL_RATE * max(distance - GATHERED, 0.0)
        )
        return self.avoid.around(observation, speed * cos, -speed * sin, speed)

    def __call__(self, observation: np.ndarray) -> int | np.ndarray:
        """The action for one observation: the steering law's, with the goal said."""
        goal = self.goal(observation)
        said = CODES[goal] if goal is not None else (0.0, 0.0)
        message = (*said, *(0.0,) * (self.width - WIDTH_NEEDED))
        action = self.steer(observation)
        if self.action_mode == "discrete":
            return int(action) * self.codes + code_of(message)
        return np.concatenate([action, np.asarray(message, dtype=np.float32)])

"""The rendezvous task's classical team controller: the scout says which landmark is the
goal, a bot that hears the scout says it again (a relay, for bots beyond the scout's
slots or range), and each bot that knows heads there with the steering law, past its
neighbours; one that knows nothing says nothing and stands.

Messages are the first two values, each -1, 0 or 1 (the nine discrete messages of a
width-2 channel): the scout says landmark k as a corner (`TOLD`: both values +-1), a
relay as an edge (`RELAYED`: one value 0), and (0, 0) says nothing. A relay never relays
a relay, so that a goal that has moved on cannot circle among bots that repeat each
other: the news travels two hops. A bot believes the scout's one-hot first, then the
nearest sender that says the scout's words, then the nearest relay.
"""

from __future__ import annotations

import numpy as np

from bbbench.policies.controllers.steer import TARGET_VELOCITY, Avoiding, SteerController
from bbbench.tasks.channel import LEVELS, Channel, code_of, nearest_level, sender_slots
from bbbench.tasks.scenarios.rendezvous import ARRIVAL_RATE, GATHERED, LANDMARKS

# Landmark k as the scout says it, and as a relay says it; (0, 0) says nothing.
TOLD = ((-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0))
RELAYED = ((-1.0, 0.0), (0.0, -1.0), (0.0, 1.0), (1.0, 0.0))
NOTHING = (0.0, 0.0)
WIDTH_NEEDED = 2  # message values the words take


def heard(values: tuple[float, float]) -> tuple[int, bool] | None:
    """What a message's first two values say: (landmark, whether the scout said it), or
    None for nothing. Each value is read as its nearest level of -1, 0 and 1."""
    first, second = (LEVELS[nearest_level(v)] for v in values)
    if (first, second) == NOTHING:
        return None
    if first and second:
        return TOLD.index((first, second)), True
    return RELAYED.index((first, second)), False


def arrival_speed(observation: np.ndarray, distance: float) -> float:
    """The speed to drive at `distance` m from where a bot gathers: the target velocity,
    slowing to stand within `GATHERED` m (the task's own law, `ARRIVAL_RATE`)."""
    return min(float(observation[TARGET_VELOCITY]), ARRIVAL_RATE * max(distance - GATHERED, 0.0))


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
        self.senders = [(slot.messages[0], slot.present) for slot in sender_slots(names)]
        self.avoid = Avoiding(names.index("neighbour1_right"), neighbours, radius=1.0)
        self.width, self.codes, self.action_mode = channel.width, channel.codes, action_mode
        self.steer = SteerController(action_mode, guide=self.guide)

    def belief(self, observation: np.ndarray) -> tuple[int | None, tuple[float, float]]:
        """The landmark this bot believes is the goal (None: none) and what it says: the
        scout's one-hot (said as `TOLD`), else the nearest sender saying the scout's words
        (said again as `RELAYED`), else the nearest relay (said as nothing)."""
        told = observation[self.told : self.told + LANDMARKS]
        if float(told.max()) > 0.5:
            goal = int(told.argmax())
            return goal, TOLD[goal]
        relayed = None
        for message, present in self.senders:
            if observation[present] > 0.5:
                said = heard((float(observation[message]), float(observation[message + 1])))
                if said is not None:
                    goal, first_hand = said
                    if first_hand:
                        return goal, RELAYED[goal]
                    if relayed is None:
                        relayed = goal
        return relayed, NOTHING

    def guide(self, observation: np.ndarray) -> tuple[float, float]:
        """The (velocity, yaw rate) towards the goal, slowing to stand within `GATHERED`
        m, past the neighbours; standing when the goal is not known."""
        goal, _ = self.belief(observation)
        if goal is None:
            return 0.0, 0.0
        at = self.landmarks[goal]
        distance, cos, sin = (float(value) for value in observation[at : at + 3])
        speed = arrival_speed(observation, distance)
        return self.avoid.around(observation, speed * cos, -speed * sin, speed)

    def __call__(self, observation: np.ndarray) -> int | np.ndarray:
        """The action for one observation: the steering law's, with the goal said."""
        _, said = self.belief(observation)
        message = (*said, *(0.0,) * (self.width - WIDTH_NEEDED))
        action = self.steer(observation)
        if self.action_mode == "discrete":
            return int(action) * self.codes + code_of(message)
        return np.concatenate([action, np.asarray(message, dtype=np.float32)])

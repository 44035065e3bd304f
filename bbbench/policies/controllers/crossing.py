"""The classical controller of the crossing tasks (MultiBalance, MultiBumps,
MultiNoisySensors): PD, plus yielding and passing, from what each bot observes of its
neighbours.

The bots cannot steer: a bot avoids another only by when it reaches the point where
their paths cross. Each step, for each neighbour in its observation, a bot predicts
(constant velocities, its own at its target) when each of the two reaches that point:

- the neighbour reaches the bot's line, `right = 0`, at `t_other = -right / right_velocity`
  (its velocity across the bot's heading), `forward + (forward_velocity + v) t_other`
  ahead of the bot (`v`: the bot's own velocity);
- the bot reaches that point at `t_self = ahead / target`.

A conflict is a crossing both reach within `horizon` s, less than `margin` s apart. The
bot that would reach it later yields: it asks PD for `slow` x its target; the earlier
one passes: it asks for `fast` x its target (at most `top_speed`). A bot in several
conflicts yields if it yields in any. A neighbour crossing behind the bot, moving along
its line (|right_velocity| < `parallel`), or not there (its block all zeros) is no
conflict. Own velocity is PD's estimate, wheel radius x (wheel speed + pitch rate).

Gains, chosen on MultiBalance-v1's training seeds 0-39 from a grid of margin, slow and
fast (`scripts/crossing_gains.py`; docs/notebook.md): horizon 3 s, margin 1.4 s, slow 0
(the later bot stops until the crossing is clear), fast 1.3, top speed 1.0 m/s, parallel
0.05 m/s. Stateless: one observation in, one action out.
"""

from __future__ import annotations

import numpy as np

from bbbench.policies.controllers.pd import PDController
from bbbench.robots.layout import INDEX
from bbbench.robots.twowheel import TWO_WHEEL
from bbbench.tasks.group import NEIGHBOUR_FIELDS

SINGLE = 5  # the shared layout's values, before the neighbours


class CrossingController:
    """The crossing law over `PDController`, for one bot of a crossing task.

    Args:
        action_mode: "discrete" or "continuous".
        horizon: s, how far ahead a crossing is looked for.
        margin: s, arrivals closer than this conflict.
        slow: the yielding bot's target, as a share of its own.
        fast: the passing bot's target, as a multiple of its own (at most `top_speed`).
        top_speed: m/s, the most the passing bot asks for.
        parallel: m/s, a neighbour slower than this across the bot's heading moves along
            its line, and crosses nowhere.
    """

    def __init__(
        self,
        action_mode: str = "discrete",
        horizon: float = 3.0,
        margin: float = 1.4,
        slow: float = 0.0,
        fast: float = 1.3,
        top_speed: float = 1.0,
        parallel: float = 0.05,
    ) -> None:
        self.pd = PDController(action_mode)
        self.horizon, self.margin = horizon, margin
        self.slow, self.fast, self.top_speed = slow, fast, top_speed
        self.parallel = parallel
        self._wheel_radius = TWO_WHEEL.wheel_radius

    def target(self, observation: np.ndarray) -> float:
        """The target velocity (m/s) the bot asks PD for: its own, or yielding, or passing."""
        target = float(observation[INDEX["target_velocity"]])
        if target <= 0.0:
            return target
        speed = self._wheel_radius * float(
            observation[INDEX["wheel_speed"]] + observation[INDEX["pitch_rate"]]
        )
        width = len(NEIGHBOUR_FIELDS)
        yields = passes = False
        for start in range(SINGLE, len(observation) - width + 1, width):
            right, forward, right_velocity, forward_velocity = (
                float(value) for value in observation[start : start + width]
            )
            if (right == 0.0 and forward == 0.0) or abs(right_velocity) < self.parallel:
                continue  # no neighbour, or one moving along the bot's line
            t_other = -right / right_velocity
            if not 0.0 < t_other < self.horizon:
                continue
            ahead = forward + (forward_velocity + speed) * t_other
            if ahead <= 0.0:
                continue  # it crosses behind the bot
            t_self = ahead / target
            if t_self > self.horizon or abs(t_self - t_other) >= self.margin:
                continue
            if t_self > t_other:
                yields = True
            else:
                passes = True
        if yields:
            return self.slow * target
        if passes:
            return min(self.fast * target, max(self.top_speed, target))
        return target

    def __call__(self, observation: np.ndarray) -> int | np.ndarray:
        """The action for one observation: PD on the target the law asks for."""
        asked = np.array(observation[:SINGLE], dtype=np.float64)
        asked[INDEX["target_velocity"]] = self.target(observation)
        return self.pd(asked)

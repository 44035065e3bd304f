"""The classical team controller of the column tasks (`bbbench.tasks.scenarios.column`):
PD on every bot, each on a target it makes from what it observes of its team.

- The front bot (no bot ahead) observes the team's target. It asks PD for that target,
  but never more than `accel` x `horizon` m/s away from its own velocity: the target
  it follows changes no faster than the bot can, so the team is not thrown.
- A follower observes 0 in the target slot. It asks PD for the velocity of the bot
  ahead (its own velocity plus the one it observes ahead) plus `pull_gain` times the
  coupling's pull forward: the hinges' force along the beam (N), or the stretch of the
  tether ahead (m).

Its own velocity is PD's estimate, wheel radius x (wheel speed + pitch rate). The law is
stateless: one observation in, one action out, so it plays any episode in any order.
"""

from __future__ import annotations

import numpy as np

from bbbench.policies.pd import PDController
from bbbench.robots.layout import INDEX

# Each coupling's reading of the pull forward, and the gain the controller gives it.
PULLS = {"hinge_force_along": 0.2, "stretch_ahead": 3.0}  # (m/s)/N and (m/s)/m


class TeamController:
    """The team law over `PDController`, for one bot of a column task.

    Args:
        layout: the names of the task's observation values, in order (the scenario's
            `layout`).
        action_mode: "discrete" or "continuous".
        accel: m/s^2, how fast the front bot's own target may pull away from its velocity.
        horizon: s, over which `accel` applies.
        pull_gain: (m/s) per unit of the coupling's pull; None: `PULLS`'s for it.
    """

    def __init__(
        self,
        layout: list[str],
        action_mode: str = "discrete",
        accel: float = 2.0,
        horizon: float = 0.25,
        pull_gain: float | None = None,
    ) -> None:
        self.pd = PDController(action_mode)
        index = {name: i for i, name in enumerate(layout)}
        missing = [
            name for name in ("ahead_present", "ahead_forward_velocity") if name not in index
        ]
        pulls = [name for name in PULLS if name in index]
        if missing or len(pulls) != 1:
            raise ValueError(
                "the team controller plays the column tasks (a beam or tethers, neighbours "
                f"ahead and behind); this layout lacks {missing or list(PULLS)}"
            )
        self._ahead = index["ahead_present"]
        self._ahead_velocity = index["ahead_forward_velocity"]
        self._pull = index[pulls[0]]
        self.pull_gain = PULLS[pulls[0]] if pull_gain is None else pull_gain
        self.reach = accel * horizon  # m/s

    def target(self, observation: np.ndarray) -> float:
        """The velocity (m/s) this bot asks PD for."""
        velocity = self.pd.wheel_radius * (
            float(observation[INDEX["wheel_speed"]]) + float(observation[INDEX["pitch_rate"]])
        )
        if observation[self._ahead] == 0.0:  # the front bot
            target = float(observation[INDEX["target_velocity"]])
            return min(max(target, velocity - self.reach), velocity + self.reach)
        ahead = velocity + float(observation[self._ahead_velocity])
        return ahead + self.pull_gain * float(observation[self._pull])

    def __call__(self, observation: np.ndarray) -> int | np.ndarray:
        """The action for one bot's observation."""
        shared = np.array(observation[: len(INDEX)], dtype=np.float32)
        shared[INDEX["target_velocity"]] = self.target(observation)
        return self.pd(shared)

"""`Column`: a team in a column, coupled and led, the base of `BeamCarry` (bots carrying
one beam, `bbbench.tasks.scenarios.beam_carry`) and `Convoy` (bots tethered each to the
next, `bbbench.tasks.scenarios.convoy`). Only the front bot observes the team's target;
the team earns one reward and a fall ends it (multiwalker's `terminate_on_fall`). Here
too: what every team task's row shares (`team_task`), and the check of a coupling's
parameters."""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from bbbench.parameters import is_real
from bbbench.robots.layout import OBSERVATION_DTYPE, ObservationField
from bbbench.tasks.commands import PiecewiseConstantVelocity
from bbbench.tasks.group import NEIGHBOUR_SPEED_RANGE
from bbbench.tasks.reward import has_fallen
from bbbench.tasks.scenario import Outcome, Pose, Scenario, Slots, fell_cause

MAX_TEAM = 4  # bots in a coupled column: the beam and tether tasks take 2 to 4
NEIGHBOUR_REACH = 5.0  # m: offsets to a neighbour saturate here
PARKED = (0.0, -2000.0, 20.0)  # m: where a coupling's body waits between episodes


def _neighbour_fields(where: str) -> tuple[ObservationField, ...]:
    reach, top = NEIGHBOUR_REACH, NEIGHBOUR_SPEED_RANGE
    return (
        ObservationField(f"{where}_present", "", 0.0, 1.0, f"1 if there is a bot {where}, else 0"),
        ObservationField(f"{where}_right", "m", -reach, reach, f"the bot {where}: to the right"),
        ObservationField(f"{where}_forward", "m", -reach, reach, "its distance ahead"),
        ObservationField(
            f"{where}_right_velocity", "m/s", -top, top, "its velocity minus this bot's, right"
        ),
        ObservationField(f"{where}_forward_velocity", "m/s", -top, top, "the same, ahead"),
    )


NEIGHBOUR_LAYOUT = _neighbour_fields("ahead") + _neighbour_fields("behind")


class Column(Scenario):
    """N bots (2 to 4) in a column on one heading, coupled by the task's `coupling`.

    The column is centred on the origin, heading along +y: bot 0 at the front, bot i
    i x spacing behind it (so a start pad about the origin holds the whole team). All
    lean by one pitch drawn from U(-initial_pitch, initial_pitch), so that the coupling
    starts at rest. The team follows one target schedule; only the
    front bot observes it (the others read 0 in the target slot) and must infer it
    from the coupling and from their neighbours.

    Team reward, the shared reward's form (`StayUpReward.terms`), the same for every
    agent: upright from the most tilted bot's pitch, tracking from the team's velocity
    (`team_velocity`) against the target. A fall of any bot, or the coupling's own end
    (`broken`), terminates every agent.
    """

    multi_agent = True
    team = True
    controller = "team"  # bbbench.policies.controllers.team: the bots as one team
    robots: ClassVar[tuple[str, ...] | None] = ("two-wheel",)  # the hinges hold its torso
    most_bots = MAX_TEAM
    coupling_type: ClassVar[type]
    coupling_layout: ClassVar[tuple[ObservationField, ...]]
    # The coupling's value that reads its pull forward on a bot (what a follower's law
    # may add to the speed of the bot ahead): a field of `coupling_layout`.
    pull_forward: ClassVar[str]

    def __init__(self, task) -> None:
        super().__init__(task)
        self.coupling = task.coupling
        self.spacing = self.coupling_spacing(task.coupling)
        team = self.coupling_layout + NEIGHBOUR_LAYOUT
        self.layout = self.robot.layout() + team
        # Each robot's fields on a mixed team (`mixes`): its own values, then the team's.
        self._layouts = {model.name: model.layout() + team for model in self.roster}
        self._layouts[self.robot.name] = self.layout
        # Each bot's robot's values, in order (a team ends whole: the i-th live bot is bot i),
        # and its rows as one array, or one array each where robots' widths differ.
        self._values = [model.values for model in self.roster]
        self._stack = _apart if task.mixed else _together
        self._bodies: tuple[int, ...] = ()
        self._client_id = -1

    @staticmethod
    def coupling_spacing(coupling: Any) -> float:
        raise NotImplementedError

    @classmethod
    def refusal(cls, task) -> str | None:
        refused = super().refusal(task)
        if refused:
            return refused
        if not isinstance(task.coupling, cls.coupling_type):
            return (
                f"{task.id}: the {cls.name!r} scenario needs a {cls.coupling_type.__name__} "
                f"coupling (its scenario's module), got {task.coupling!r}"
            )
        return None

    # -- the world and the start ----------------------------------------------------

    def build(self, client, bots) -> None:
        self._client = client
        self._client_id = bots[0].client_id
        self._bodies = tuple(bot.body for bot in bots)

    def starts(self, rng: np.random.Generator) -> tuple[list[Pose], list[float]]:
        pitch = float(rng.uniform(-self.task.initial_pitch, self.task.initial_pitch))
        n = self.n_bots
        front = (n - 1) / 2 * self.spacing
        return [((0.0, front - self.spacing * i), 0.0) for i in range(n)], [pitch] * n

    def targets(self, rng: np.random.Generator) -> list[list[float]]:
        task = self.task
        row = task.command.targets(rng, task.max_episode_steps, task.control_dt)
        return [row] * self.n_bots  # one schedule: the team's

    # -- observations ----------------------------------------------------------------

    def bot_layout(self, bot: int) -> tuple[ObservationField, ...]:
        return self._layouts[self.roster[bot].name] if self.task.mixed else self.layout

    def slots(self) -> Slots:
        """The robot's own values and the coupling's, then the bots ahead and behind,
        each slot led by its presence bit."""
        return self.bot_slots(0)

    def bot_slots(self, bot: int) -> Slots:
        width = len(NEIGHBOUR_LAYOUT) // 2
        return Slots(len(self.bot_layout(bot)) - 2 * width, 2, width, 0)

    def observe(
        self, scene: Any, states: list[Any], commands: list[float], targets: list[float], step: int
    ) -> np.ndarray:
        """Each bot's row: its robot's values (the front bot's target; 0 for the others),
        what it observes of the coupling, and its neighbours ahead and behind."""
        self.read(states)
        n = len(states)
        rows = []
        for i, (state, values) in enumerate(zip(states, self._values, strict=True)):
            reading = (state.pitch, state.pitch_rate, state.wheel_speed)
            row = [*values(reading, commands[i], targets[i] if i == 0 else 0.0, state)]
            row += self.coupling_terms(i)
            row += _neighbour(state, states[i - 1]) if i > 0 else _ABSENT
            row += _neighbour(state, states[i + 1]) if i + 1 < n else _ABSENT
            rows.append(row)
        return self._stack(rows)

    def read(self, states: list[Any]) -> None:
        """Read the coupling once, after each reset and step (before `outcome`)."""
        raise NotImplementedError

    def coupling_terms(self, index: int) -> list[float]:
        """What bot `index` observes of the coupling (`coupling_layout`), from `read`."""
        raise NotImplementedError

    # -- the team's outcome ---------------------------------------------------------

    def team_velocity(self, states: list[Any]) -> float:
        """The team's forward velocity (m/s), scored against the target."""
        raise NotImplementedError

    def broken(self) -> bool:
        """Whether the coupling itself ended the episode (from `read`)."""
        return False

    broken_cause: ClassVar[str] = "the coupling broke"  # an Outcome's cause when it does

    def scored(
        self, pitch: float, states: list[Any], target: Any
    ) -> tuple[float, float, dict[str, float]]:
        """The team reward's two terms from the most tilted `pitch` and the team's
        `target`, and the errors they were scored on (info keys): the team's velocity
        against the target velocity."""
        velocity_error = abs(self.team_velocity(states) - target)
        upright, velocity = self.reward.terms(pitch, velocity_error)
        return upright, velocity, {"velocity_error": velocity_error}

    def outcome(
        self, agents: list[str], states: list[Any], targets: list[float], seed: int
    ) -> Outcome:
        """The team's reward, computed once, for every bot; the episode is over for all
        of them at a fall of any bot or when the coupling breaks, and the cause names
        the bots that fell and a broken coupling."""
        pitch = max((state.pitch for state in states), key=abs)
        upright, velocity, errors = self.scored(pitch, states, targets[0])
        fell = [has_fallen(state) for state in states]
        broken = self.broken()
        cause = "; ".join(
            [c for c in (fell_cause(agents, fell), self.broken_cause if broken else "") if c]
        )
        info = {"reward_upright": upright, "reward_velocity": velocity, **errors}
        info["episode_seed"] = seed
        return Outcome(
            [upright + velocity] * len(agents),
            fell,
            broken or any(fell),
            cause,
            [dict(info) for _ in agents],
        )


_ABSENT = [0.0] * 5


def _neighbour(state: Any, other: Any) -> list[float]:
    """[present, right, forward, right velocity, forward velocity] of `other` in the frame
    of `state`'s bot (between torso centres, horizontally; axle velocities), saturated."""
    forward_x, forward_y = state.heading
    turn = complex(forward_y, forward_x)  # i * conj(heading): world -> right + i ahead
    offset = complex(other.position[0] - state.position[0], other.position[1] - state.position[1])
    offset *= turn
    moving = (complex(*other.velocity) - complex(*state.velocity)) * turn
    reach, top = NEIGHBOUR_REACH, NEIGHBOUR_SPEED_RANGE
    return [
        1.0,
        min(max(offset.real, -reach), reach),
        min(max(offset.imag, -reach), reach),
        min(max(moving.real, -top), top),
        min(max(moving.imag, -top), top),
    ]


def check_ranges(component: object, ranges: dict[str, tuple[float, float]], units: dict[str, str]):
    """A ValueError naming the first parameter outside its physical range."""
    name = type(component).__name__
    for field, (low, high) in ranges.items():
        value = getattr(component, field)
        if not is_real(value) or not math.isfinite(value) or not low <= value <= high:
            raise ValueError(
                f"{name} {field} must be a number in [{low:g}, {high:g}] {units[field]}, "
                f"got {value!r}"
            )
        object.__setattr__(component, field, float(value))


# What every team task's row shares: coupled bots, one team reward, led by the front bot,
# the only one that observes the target; targets fast enough that bots which ignore the
# coupling are thrown. Each row states the rest (MultiBalance-v1's reward, control rate,
# time limit and evaluation seeds, and its own scenario and coupling).
TEAM_TARGETS = PiecewiseConstantVelocity(low=-2.0, high=2.0, hold=(2.0, 5.0))
TEAM_HISTORY = ("v0: initial release, on the shared reward's team form (Column).",)
_TEAM_WHY = """\
Only the front bot observes the team's target velocity; the others read 0 in that slot
and must infer it from the coupling and from their neighbours. Targets are drawn from
[-2, 2] m/s (the bot's top speed is 2.46 m/s) and held 2-5 s, as VelocityTracking's: at
these speeds bots that ignore each other are thrown (at [-1, 1] m/s a hinged beam never
threw PD). Every agent receives the team's reward, `StayUpReward.terms(pitch, error)`
with the most tilted bot's pitch and `error` = |team velocity - target|: each step earns
0-0.1, 0.01 for the team being upright and up to 0.09 more for its tracking. A fall of
any bot ends every agent's episode (multiwalker's `terminate_on_fall`). The observation
(19 values per bot, the table in `bbbench.envs.multi`): the shared five, four of the
coupling, then the bot ahead and the bot behind, each with a presence bit. The naive
baseline is `pd` (a follower holds the 0 it observes); the classical team controller is
`team` (`bbbench.policies.controllers.team`); docs/tasks.md has the calibration."""


def team_description(description: str, shared: str = _TEAM_WHY) -> str:
    """A team task's description, then what the team tasks of its robot share."""
    return f"{description}\n\n{shared}"


def _together(rows: list[list[float]]) -> np.ndarray:
    """One robot's rows, all of its width: one array."""
    return np.array(rows, dtype=OBSERVATION_DTYPE)


def _apart(rows: list[list[float]]) -> list[np.ndarray]:
    """A mixed team's rows, each of its robot's width: one array each."""
    return [np.array(row, dtype=OBSERVATION_DTYPE) for row in rows]

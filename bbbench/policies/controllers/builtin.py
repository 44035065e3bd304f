"""The classical baselines and reference policies every task can be scored against:
PD, stand (PD holding 0 m/s), LQR, random and zero; the team tasks' own, team; the
crossing tasks' own, crossing; the wheel-legged robot's, legged; and the steering
robot's, steer."""

from __future__ import annotations

import numpy as np

from bbbench.policies.controllers.crossing import CrossingController
from bbbench.policies.controllers.legged import LeggedController
from bbbench.policies.controllers.lqr import LQRController
from bbbench.policies.controllers.pd import PDController
from bbbench.policies.controllers.rendezvous import RendezvousController
from bbbench.policies.controllers.steer import GUIDES, Avoiding, SteerController
from bbbench.policies.controllers.team import (
    MIXED_LEG_LENGTH,
    LeggedTeam,
    SteeringTeam,
    TeamController,
)
from bbbench.policies.policy import (
    Actor,
    ConstantActor,
    PDActor,
    Policy,
    RandomActor,
    TeamActor,
    describe_space,
    mixed_mismatch,
)
from bbbench.robots import ROBOTS
from bbbench.robots.twowheel import WHEEL_SPEED_CHANGES
from bbbench.tasks.scenarios import Column, Crossing, Rendezvous
from bbbench.tasks.suite import agent_layout, agent_spaces, list_tasks, spec


class TwoWheelPolicy(Policy):
    """A policy of the two-wheel robot's actions: it fits that robot's tasks only."""

    robot = "two-wheel"

    def mismatch(self, task_id: str) -> str | None:
        return robot_mismatch(self, task_id)


def robot_mismatch(policy: Policy, task_id: str) -> str | None:
    """Why `policy`, made for the robot `policy.robot`, cannot play `task_id`, or None."""
    task = spec(task_id)
    if task.mixed:
        return mixed_mismatch(policy, task_id)
    robot = task.robot
    if robot == policy.robot:
        return None
    return f"{task_id} plays the {robot} robot; {policy.name} controls the {policy.robot} robot"


class PDPolicy(TwoWheelPolicy):
    """The PD baseline (`bbbench.policies.PDController`): reads only the shared layout, so
    it fits every task of the two-wheel robot."""

    name = algorithm = "pd"
    hold_velocity: float | None = None  # m/s held instead of the task's target; None tracks it

    def __init__(self, action_mode: str = "discrete") -> None:
        self.action_mode = action_mode

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        return PDActor(PDController(action_mode=self.action_mode, hold_velocity=self.hold_velocity))


class StandPolicy(PDPolicy):
    """The PD baseline holding target velocity 0 whatever the task asks: it stays up and
    does not drive, so its score is what a task pays for staying up alone. On
    FlatBalance, whose target is 0, it is the PD baseline itself."""

    name = algorithm = "stand"
    hold_velocity = 0.0


class LQRPolicy(TwoWheelPolicy):
    """The LQR baseline (`bbbench.policies.controllers.lqr.LQRController`): designed from a model
    identified from the simulator; reads only the shared layout, so it fits every task of
    the two-wheel robot."""

    name = algorithm = "lqr"

    def __init__(self, action_mode: str = "discrete") -> None:
        self.action_mode = action_mode

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        return PDActor(LQRController(action_mode=self.action_mode))


class TeamPolicy(TwoWheelPolicy):
    """The team tasks' classical controller (`bbbench.policies.controllers.team.TeamController`): PD
    on a target each bot makes from its team, the front bot's target limited in how fast
    it changes, a follower's from the bot ahead and the coupling's pull. It plays the
    column tasks (BeamCarry, BeamCarryBumps, Convoy) only; on them, `pd` is the naive
    baseline (a follower holds the 0 it observes). On a column of steering bots
    (ConvoyTurns) it steers too (`SteeringTeam`): the front bot as commanded, a
    follower after the bot ahead."""

    name = algorithm = "team"
    robots = ("two-wheel", "two-wheel-steer")

    def __init__(self, action_mode: str = "discrete") -> None:
        self.action_mode = action_mode

    def mismatch(self, task_id: str) -> str | None:
        task = spec(task_id)
        if task.mixed:
            return mixed_mismatch(self, task_id) + " (mixed-team plays it)"
        if task.robot not in self.robots:
            return (
                f"{task_id} plays the {task.robot} robot; team controls {' and '.join(self.robots)}"
            )
        if not _is_team(task_id):
            teams = [t for t in list_tasks(multi_agent=True, latest=True) if _is_team(t)]
            return f"{task_id} is not a team task; team plays {', '.join(teams)}"
        return None

    def spaces_text(self) -> str:
        spaces = " or ".join(
            f"{robot} robot -> {describe_space(ROBOTS[robot].action_space(self.action_mode))}"
            for robot in self.robots
        )
        return f"the column tasks: {spaces}"

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        task = spec(task_id)
        scenario = task.scenario_class(task)
        if scenario.steers:
            return PDActor(SteerController(self.action_mode, guide=SteeringTeam(scenario)))
        return PDActor(TeamController.for_scenario(scenario, self.action_mode))


def _is_team(task_id: str) -> bool:
    return issubclass(spec(task_id).scenario_class, Column)


class MixedTeamPolicy(Policy):
    """The mixed team's classical controller (`bbbench.policies.controllers.team`): the
    team law on every bot, tracked by PD on a two-wheel bot and by the wheel-legged
    robot's controller on a wheel-legged one (`LeggedTeam`), its legs riding at
    `MIXED_LEG_LENGTH`. It plays the mixed teams' tasks (MixedBeamCarry,
    MixedBeamCarryBumps) only; on them, `per-bot` is the naive baseline."""

    name = algorithm = "mixed-team"
    action_mode = "continuous"
    naive = False  # `per-bot`: each robot's own controller on what it observes

    def __init__(self, leg_length: float = MIXED_LEG_LENGTH) -> None:
        self.leg_length = leg_length  # m, hip to axle: a wheel-legged robot's legs

    def mismatch(self, task_id: str) -> str | None:
        if spec(task_id).mixed:
            return None
        mixed = [t for t in list_tasks(multi_agent=True, latest=True) if spec(t).mixed]
        return f"{task_id} is not a mixed team's task; {self.name} plays {', '.join(mixed)}"

    def spaces_text(self) -> str:
        spaces = " or ".join(
            f"{robot} robot -> {describe_space(ROBOTS[robot].action_space(self.action_mode))}"
            for robot in ("two-wheel", "wheel-legged")
        )
        return f"the mixed teams' tasks: {spaces}"

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        task = spec(task_id)
        scenario = task.scenario_class(task)
        actors = {}
        for name, bots in task.robot_groups.items():
            # Each robot by its own controller (`Robot.controller`): PD, or `legged`.
            own = ROBOTS[name].controller
            if self.naive:
                controller = LeggedController() if own == "legged" else PDController("continuous")
            else:
                team = (scenario.bot_layout(bots[0]), scenario.pull_forward)
                controller = (
                    LeggedTeam(*team, self.leg_length)
                    if own == "legged"
                    else TeamController(*team, "continuous")
                )
            actors[name] = PDActor(controller)
        return TeamActor(actors, task.robots)


class PerBotPolicy(MixedTeamPolicy):
    """The mixed teams' naive baseline: each bot its robot's own classical controller (PD
    on a two-wheel bot, `legged` on a wheel-legged one) on the target it observes, so a
    follower holds the 0 it reads, as `pd` is on the one-robot teams."""

    name = algorithm = "per-bot"
    naive = True


class CrossingPolicy(TwoWheelPolicy):
    """The crossing tasks' classical controller (`bbbench.policies.controllers.crossing`): PD, the
    bot that would reach a crossing later yielding and the earlier one passing, from
    the neighbours it observes. It plays the crossing tasks (MultiBalance, MultiBumps)
    only; on them, `pd` is the baseline the targets are set against."""

    name = algorithm = "crossing"

    def __init__(self, action_mode: str = "discrete") -> None:
        self.action_mode = action_mode

    def mismatch(self, task_id: str) -> str | None:
        refused = robot_mismatch(self, task_id)
        if refused is None and not issubclass(spec(task_id).scenario_class, Crossing):
            crossings = [
                t
                for t in list_tasks(multi_agent=True, latest=True)
                if issubclass(spec(t).scenario_class, Crossing)
            ]
            return f"{task_id} is not a crossing task; crossing plays {', '.join(crossings)}"
        return refused

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        return PDActor(CrossingController(self.action_mode))


class LeggedPolicy(Policy):
    """The wheel-legged robot's classical controller (`bbbench.policies.controllers.legged`): PD on
    the wheels from the balance pitch, the legs riding low and damping the torso's roll. It
    fits every task of the wheel-legged robot."""

    name = algorithm = "legged"
    robot = "wheel-legged"
    action_mode = "continuous"

    def mismatch(self, task_id: str) -> str | None:
        return robot_mismatch(self, task_id)

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        return PDActor(LeggedController())


class SteerPolicy(Policy):
    """The steering robot's classical controller (`bbbench.policies.controllers.steer`):
    PD balance on the forward command and a yaw-rate law on the turning command, towards
    the (velocity, yaw rate) its task asks for or that heads for its goal. It fits every
    steering task whose scenario says what a bot heads for (`Scenario.heads_for`)."""

    name = algorithm = "steer"
    robot = "two-wheel-steer"

    def __init__(self, action_mode: str = "discrete") -> None:
        self.action_mode = action_mode

    def mismatch(self, task_id: str) -> str | None:
        refused = robot_mismatch(self, task_id)
        scenario = spec(task_id).scenario_class
        if refused is None and scenario.heads_for not in GUIDES:
            return f"{task_id}: steer has no guide for its {scenario.name!r} scenario"
        return refused

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        scenario = spec(task_id).scenario_class
        return PDActor(SteerController.for_scenario(scenario, self.action_mode))


class SteerAvoidPolicy(SteerPolicy):
    """`steer` with collision avoidance (`bbbench.policies.controllers.steer.Avoiding`):
    each bot heads for its goal, pushed away from the neighbours it observes within
    1.5 m and keeping to the right of the one ahead. It plays the multi-bot tasks whose
    bots head for goals (Swap); on them, `steer` is the law without avoidance."""

    name = algorithm = "steer-avoid"

    def mismatch(self, task_id: str) -> str | None:
        refused = robot_mismatch(self, task_id)
        if refused is None and not _among_others_to_goals(task_id):
            plays = [t for t in list_tasks(latest=True) if _among_others_to_goals(t)]
            return (
                f"{task_id} is not a task of bots each heading for a goal among the others; "
                f"steer-avoid plays {', '.join(plays)}"
            )
        return refused

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        task = spec(task_id)
        slots = task.scenario_class(task).slots()
        guide = Avoiding(slots.own, slots.count, radius=1.5, keep_right=2.0)
        return PDActor(SteerController(self.action_mode, guide=guide))


def _among_others_to_goals(task_id: str) -> bool:
    scenario = spec(task_id).scenario_class
    return scenario.multi_agent and scenario.heads_for == "the goal"


class RendezvousPolicy(SteerPolicy):
    """The rendezvous tasks' classical team controller
    (`bbbench.policies.controllers.rendezvous`): the scout says the goal's landmark over
    the channel, every bot that heard it says it again, and each bot that knows steers
    there past its neighbours (one that knows nothing stands). It plays the tasks of the
    rendezvous scenario only; on them, the same controller with the messages muted
    (`mute_messages=True`) is what the channel is measured against."""

    name = algorithm = "rendezvous"

    def mismatch(self, task_id: str) -> str | None:
        refused = robot_mismatch(self, task_id)
        if refused is None and not issubclass(spec(task_id).scenario_class, Rendezvous):
            plays = [t for t in list_tasks(latest=True) if _is_rendezvous(t)]
            return f"{task_id} is not a rendezvous task; rendezvous plays {', '.join(plays)}"
        return refused

    def spaces_text(self) -> str:
        spaces = ", ".join(
            f"{t} -> {describe_space(agent_spaces(t, self.action_mode)[1])}"
            for t in list_tasks(latest=True)
            if _is_rendezvous(t)
        )
        return f"the rendezvous tasks: {spaces}"

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        task = spec(task_id)
        layout = agent_layout(task_id)
        controller = RendezvousController(
            layout, task.channel, task.group.neighbours, self.action_mode
        )
        return PDActor(controller)


def _is_rendezvous(task_id: str) -> bool:
    return issubclass(spec(task_id).scenario_class, Rendezvous)


class RandomPolicy(Policy):
    """Uniformly random actions: the 0 of the normalized score. It always acts
    stochastically, from the episode's seeded generator."""

    name = algorithm = "random"
    random_actions = True

    def __init__(self, action_mode: str = "discrete") -> None:
        self.action_mode = action_mode

    def mismatch(self, task_id: str) -> str | None:
        task = spec(task_id)
        robot = task.robot_model
        if self.action_mode in task.action_modes:
            return None
        if task.mixed:
            return (
                f"{task_id}'s robots ({' and '.join(task.robots)}) take "
                f"{' or '.join(task.action_modes)} actions, not {self.action_mode} ones "
                f"(--action-mode {task.default_action_mode})"
            )
        return (
            f"{task_id} plays the {robot.name} robot, which takes {' or '.join(robot.action_modes)}"
            f" actions, not {self.action_mode} ones (--action-mode {robot.default_action_mode})"
        )

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        task = spec(task_id)
        if task.mixed:  # each robot's bots in its own space
            actors = {
                name: RandomActor(task.action_space(self.action_mode, bots[0]))
                for name, bots in task.robot_groups.items()
            }
            return TeamActor(actors, task.robots)
        return RandomActor(agent_spaces(task_id, self.action_mode)[1])


class ZeroPolicy(TwoWheelPolicy):
    """Never change the wheel command: the bot is left to fall (a lower bound)."""

    name = algorithm = "zero"

    def __init__(self, action_mode: str = "discrete") -> None:
        self.action_mode = action_mode

    def actor(self, task_id: str, deterministic: bool = True) -> Actor:
        if self.action_mode == "discrete":
            return ConstantActor(WHEEL_SPEED_CHANGES.index(0.0))
        return ConstantActor(np.zeros(1, dtype=np.float32))

"""A policy read from a file (a zip, an ONNX model): the tasks its spaces fit.

A file declares the observation it reads (a width) and its action space; it
fits a task whose bot observes and acts in those. The layout tells the robot
(and whether the height scan follows): the two-wheel bot's 5 or 16, the
wheel-legged robot's 17 or 28 (with Box(6) actions), the multi-bot 17 and the
team tasks' 19 (with the two-wheel bot's actions).
"""

from __future__ import annotations

from gymnasium import spaces

from bbbench.policies.policy import Policy, describe_space, mixed_mismatch
from bbbench.robots import ROBOTS
from bbbench.tasks.suite import agent_spaces, list_tasks, spec

# The most parameters bbbench evaluates in a policy file, in any format (a zip's
# policy.pth and the network it declares, an ONNX file's tensors): some 40 MB of
# float32, far beyond the MLPs these tasks need (a 64 x 64 PPO has ~10k).
MAX_PARAMETERS = 10_000_000


class FilePolicy(Policy):
    """A policy whose file declares `observation_shape` and `action_space`."""

    observation_shape: tuple[int, ...]
    action_space: spaces.Discrete | spaces.Box

    def _set_layout(self) -> None:
        # The robot whose single-bot layout it observes (None: none, a multi-bot policy), and
        # whether the height scan follows: its tasks are played with it.
        self.robot, self.height_scan = single_bot_layout(self.observation_shape, self.action_space)

    def _fits(self, task_id: str) -> bool:
        task = spec(task_id)
        if task.mixed or self.action_mode not in task.robot_model.action_modes:
            return False
        return self.reads(*agent_spaces(task_id, self.action_mode, self.height_scan))

    def reads(self, observation_space: spaces.Box, action_space: spaces.Space) -> bool:
        """Whether the file's policy observes `observation_space` and acts in
        `action_space` (a bot's, or a mixed team's group's)."""
        return observation_space.shape == self.observation_shape and (
            describe_space(action_space) == describe_space(self.action_space)
        )

    def mismatch(self, task_id: str) -> str | None:
        if self._fits(task_id):
            return None
        task = spec(task_id)
        if task.mixed:
            return mixed_mismatch(self, task_id)
        robot = task.robot_model
        if task.multi_agent:
            wants = describe_space(agent_spaces(task_id, robot.default_action_mode)[0])
        else:  # the task's own observation: the robot's layout, or a scenario's on top
            observation = agent_spaces(task_id, robot.default_action_mode)[0]
            own = observation.shape == robot.observation_space(False).shape
            wants = robot.describe_layout() if own else describe_space(observation)
            if task.scenario_class.scans_ground:
                scanned = agent_spaces(task_id, robot.default_action_mode, height_scan=True)[0]
                wants += f" (or {describe_space(scanned)} with height_scan=True)"
        actions = " or ".join(
            describe_space(robot.action_space(mode)) for mode in robot.action_modes
        )
        reason = f"{task_id} plays the {robot.name} robot and wants {wants} -> {actions}"
        if self.robot is not None and self.robot != robot.name:
            mine = ROBOTS[self.robot]
            fits = [t for t in list_tasks(latest=True) if self._fits(t)]
            reason += (
                f"; the policy observes the {mine.name} robot's "
                f"{mine.describe_layout(self.height_scan)}, and fits "
                f"{', '.join(fits) or 'no task of the suite'}"
            )
        return reason

    def spaces_text(self) -> str:
        return f"Box{self.observation_shape} -> {describe_space(self.action_space)}"


def single_bot_layout(
    observation_shape: tuple[int, ...], action_space: spaces.Space
) -> tuple[str | None, bool]:
    """(robot name, height scan) of the single-bot layout a policy observes, and acts in;
    (None, False) for none (a multi-bot policy's)."""
    for robot in ROBOTS.values():
        for height_scan in (False, True):
            if robot.observation_space(height_scan).shape == observation_shape and any(
                describe_space(robot.action_space(mode)) == describe_space(action_space)
                for mode in robot.action_modes
            ):
                return robot.name, height_scan
    return None, False

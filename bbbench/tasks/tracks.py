"""The leaderboard's tracks, each declared once: its title, the tasks it ranks (derived
from the suite: a robot's single-bot, multi-bot or team tasks) and the task its entries' robustness
profile plays. The board (`bbbench.leaderboard`), the CLI's track choices and the profile
protocol (`bbbench.evaluation.profile`) all read this table."""

from __future__ import annotations

import dataclasses

from bbbench.tasks.spec import TaskSpec
from bbbench.tasks.suite import SUITE, latest_version


@dataclasses.dataclass(frozen=True)
class Track:
    """One ranking: the tasks of one robot, played by one bot, by several, or by a team
    (coupled bots that share one reward: a scenario whose `team` is set), without a
    message channel or with one."""

    name: str  # what the board document and `--track` say
    label: str  # how messages name it: 'the single-bot track'
    title: str  # the board's heading
    robot: str  # `TaskSpec.robot`
    multi_agent: bool  # several bots in one world (one policy shared by every bot)
    profile_task: str  # a task of the track: its latest version is what profiles play
    team: bool = False  # a team's tasks (cooperative), not bots each on their own
    talks: bool = False  # tasks whose bots talk over a message channel (`TaskSpec.channel`)
    # Its entries get a team-size profile too (`bbbench.evaluation.team_sizes`): the profile
    # task played with 2, 4, 6 and 8 bots.
    team_sizes: bool = False
    # A mixed team's tasks (`TaskSpec.robots`): `robot` leads, and each robot's bots have a
    # policy of their own.
    mixed: bool = False

    def __post_init__(self) -> None:
        if not self.holds(SUITE[self.profile_task]):
            raise ValueError(
                f"track {self.name}: its profile task {self.profile_task} is not its own"
            )

    def holds(self, task: TaskSpec) -> bool:
        """Whether the track ranks `task` (any version of it)."""
        return (
            task.robot == self.robot
            and task.multi_agent == self.multi_agent
            and task.scenario_class.team == self.team
            and (task.channel is not None) == self.talks
            and task.mixed == self.mixed
        )

    @property
    def profiled_on(self) -> str:
        """The latest version of the profile task: what its entries' profiles play."""
        return latest_version(self.profile_task)


# In the board's order.
TRACKS: dict[str, Track] = {
    track.name: track
    for track in (
        Track(
            "single",
            "single-bot",
            "single-bot tasks",
            "two-wheel",
            False,
            "bbbench/VelocityTracking-v1",
        ),
        Track(
            "multi",
            "multi-bot",
            "multi-bot tasks (one policy shared by every bot)",
            "two-wheel",
            True,
            "bbbench/MultiBalance-v1",
            team_sizes=True,
        ),
        Track(
            "cooperative",
            "cooperative",
            "cooperative tasks (coupled bots, one team reward, one policy shared by every bot)",
            "two-wheel",
            True,
            "bbbench/BeamCarry-v0",
            team=True,
        ),
        Track(
            "mixed-team",
            "mixed-team",
            "a mixed team's tasks (wheel-legged robots and two-wheel bots carrying one beam, "
            "one team reward, one policy per robot)",
            "wheel-legged",
            True,
            "bbbench/MixedBeamCarry-v0",
            team=True,
            mixed=True,
        ),
        Track(
            "wheel-legged",
            "wheel-legged",
            "the wheel-legged robot's tasks",
            "wheel-legged",
            False,
            "bbbench/LeggedVelocityTracking-v0",
        ),
        Track(
            "steering",
            "steering",
            "the steering robot's tasks (its wheels commanded apart)",
            "two-wheel-steer",
            False,
            "bbbench/SteerTracking-v0",
        ),
        Track(
            "steering-multi",
            "multi-bot steering",
            "the steering robot's multi-bot tasks (one policy shared by every bot)",
            "two-wheel-steer",
            True,
            "bbbench/Swap-v0",
            team_sizes=True,
        ),
        Track(
            "steering-cooperative",
            "steering cooperative",
            "the steering robot's cooperative tasks (a tethered team, one team reward)",
            "two-wheel-steer",
            True,
            "bbbench/ConvoyTurns-v0",
            team=True,
        ),
        Track(
            "steering-talk",
            "steering with messages",
            "the steering robot's tasks with a message channel (one team reward, one policy "
            "shared by every bot)",
            "two-wheel-steer",
            True,
            "bbbench/Rendezvous-v0",
            talks=True,
        ),
    )
}


def track_of(task: TaskSpec) -> Track:
    """The track that ranks `task`; a clear error for a task no track holds."""
    for track in TRACKS.values():
        if track.holds(task):
            return track
    kind = "multi-bot" if task.multi_agent else "single-bot"
    raise ValueError(
        f"{task.id}: no track ranks the {task.robot} robot's {kind} tasks; declare one in "
        f"bbbench/tasks/tracks.py"
    )

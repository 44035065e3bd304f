"""Team-size profiles: how a policy shared by every bot plays teams of another size.

A multi-bot task's `n_bots` is a keyword of its env and an axis of `bbbench sweep`; a
team-size profile is that axis played as the robustness profile plays its axes
(`bbbench.evaluation.profile`): the track's profile task (MultiBalance-v1, Swap-v0) at
each of `SIZES` bots, on the first `PROFILE_EPISODES` evaluation seeds, deterministic
actions, every episode recorded in a profile document whose one axis is `n_bots`. Its
points are normalized scores as the board's (a task's return is the mean of its bots'
shares, so a size's score reads as the default size's does). The board gives every run
on a track that declares `team_sizes` (`bbbench.tasks.tracks`) one, beside its
robustness profile, and marks the size its method trained with.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from bbbench.evaluation.profile import PROFILE_EPISODES
from bbbench.evaluation.sweep import variant
from bbbench.tasks.spec import TaskSpec
from bbbench.tasks.suite import spec

AXIS = "n_bots"
SIZES = (2, 4, 6, 8)
# Bumped when the protocol plays anything else: a stored profile is reused only when its
# protocol matches.
TEAM_SIZES_VERSION = 1
SUFFIX = ".sizes.json"  # results/<slug>.<track>.sizes.json


def sizes_file(slug: str, track: str) -> str:
    """The name of a run's team-size profile on a track, in the board's results folder."""
    return f"{slug}.{track}{SUFFIX}"


@dataclasses.dataclass(frozen=True)
class TeamSizes:
    """What a team-size profile plays: the first `episodes` eval seeds with each of
    `sizes` bots. The board's is `TEAM_SIZES`; a smaller one makes a board for tests."""

    episodes: int = PROFILE_EPISODES
    sizes: tuple[int, ...] = SIZES

    def record(self, task_id: str) -> dict[str, Any]:
        return {
            "version": TEAM_SIZES_VERSION,
            "task": task_id,
            "episodes": self.episodes,
            "axes": {AXIS: list(self.sizes)},
        }

    def specs(self, task_id: str, height_scan: bool = False) -> list[tuple[str, int, TaskSpec]]:
        """Every (axis, size, spec) point on `task_id`; a `ValueError` (one line) for a size
        outside the task's range."""
        task = spec(task_id).with_height_scan(height_scan)
        return [(AXIS, size, checked_variant(task, size)) for size in self.sizes]


def checked_variant(task: TaskSpec, size: int) -> TaskSpec:
    """`task` with `size` bots, or a `ValueError` that names the task's range."""
    try:
        return variant(task, AXIS, size)
    except (TypeError, ValueError) as error:
        raise ValueError(f"team-size profile on {task.id}: {error}") from None


def trained_size(run_record: dict[str, Any], task_id: str) -> int | None:
    """The bots per world a run's method trained with, marked on `task_id`'s profile: its
    recipe's `n_bots` when the run says it, else the size of the multi-bot task it trained
    on (its recipe's first), else `task_id`'s own; None for a policy that was not trained
    (a controller: no world steps)."""
    recipe = run_record.get("recipe") or {}
    if not recipe.get("world_steps"):
        return None
    trained_on = [spec(t) for t in recipe.get("tasks", ()) if spec(t).multi_agent]
    group = (trained_on[0] if trained_on else spec(task_id)).group
    return int(recipe.get("n_bots", group.n_bots))


TEAM_SIZES = TeamSizes()

"""Robustness profiles: one fixed, cheap protocol that gives every policy a measured
profile on the standard axes (`bbbench.tasks.perturbations`).

The protocol (`PROTOCOL`, a `Protocol`): on each leaderboard track a policy plays the
latest version of the track's profile task (`bbbench.tasks.tracks`: VelocityTracking on
the single-bot track, MultiBalance on the multi-bot one, where `sensor_noise` does not
apply, BeamCarry on the cooperative one, which takes neither `sensor_noise` nor
`com_offset` and puts `payload_mass` on the beam, LeggedVelocityTracking on the
wheel-legged one), at each value of each axis's
standard grid, on the first `PROFILE_EPISODES` evaluation seeds,
with deterministic actions; every (axis, value) point through the harness's player, all
on one pool of workers. Per axis the robustness score is the mean normalized score over
its grid and the worst case the least; the profile's own are the mean of the axes'
scores (each axis weighs the same) and the least point of all.

The profile document (`bbbench-profile/2`) keeps every episode's record, so that its
aggregates can be computed again from it (`profile_document`), as the leaderboard's
check does.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

import bbbench
from bbbench.evaluation.harness import play_tasks
from bbbench.evaluation.play import PlayedEpisode
from bbbench.evaluation.results import HARNESS_VERSION, aggregate
from bbbench.evaluation.sweep import robustness, unit, variant
from bbbench.policies.policy import Policy
from bbbench.portable import total
from bbbench.tasks.perturbations import PERTURBATIONS, refusal
from bbbench.tasks.spec import TaskSpec
from bbbench.tasks.suite import spec
from bbbench.tasks.tracks import TRACKS

# 2: the text holds each point's episodes as a table (`results.dumps`), where 1 wrote one
# object per episode; a profile of either is read for its episodes.
SCHEMA = "bbbench-profile/2"
EPISODES_OF = ("bbbench-profile/1", SCHEMA)
PROFILE_EPISODES = 20
# Bumped when the protocol plays anything else: a stored profile is reused only when its
# protocol matches.
PROTOCOL_VERSION = 1


@dataclasses.dataclass(frozen=True)
class Protocol:
    """What a profile plays: the first `episodes` eval seeds at each value of each of
    `axes` (those that apply to the task). The board's is `PROTOCOL`; a smaller one
    makes a board for tests."""

    episodes: int = PROFILE_EPISODES
    axes: tuple[str, ...] = tuple(PERTURBATIONS)

    def record(self, task_id: str) -> dict[str, Any]:
        """What a profile on `task_id` plays, as the profile document records it."""
        return {
            "version": PROTOCOL_VERSION,
            "task": task_id,
            "episodes": self.episodes,
            "axes": {axis: list(PERTURBATIONS[axis].grid) for axis in self.applying(task_id)},
        }

    def applying(self, task_id: str) -> list[str]:
        """The axes that apply to the task: all, but those that change what the sensors
        read on a multi-bot task (its sensors are its own)."""
        task = spec(task_id)
        return [axis for axis in self.axes if refusal(axis, task) is None]

    def specs(self, task_id: str, height_scan: bool = False) -> list[tuple[str, float, TaskSpec]]:
        """Every (axis, value, spec) point of the protocol on `task_id`, axis by axis."""
        task = spec(task_id).with_height_scan(height_scan)
        return [
            (axis, value, variant(task, axis, value))
            for axis in self.applying(task_id)
            for value in PERTURBATIONS[axis].grid
        ]


PROTOCOL = Protocol()


def profile_task(policy: Policy) -> str | None:
    """The task the protocol profiles `policy` on first: the profile task of the first
    track (in the board's order) whose profile task it fits; None if it fits none."""
    for track in TRACKS.values():
        if policy.mismatch(track.profiled_on) is None:
            return track.profiled_on
    return None


def profile(
    policy: Policy,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
    on_result: Callable[[int, list[PlayedEpisode] | None], None] | None = None,
    protocol: Protocol = PROTOCOL,
    task_id: str | None = None,
) -> dict[str, Any]:
    """Play the protocol (the robustness `Protocol`, or a team-size one,
    `bbbench.evaluation.team_sizes.TeamSizes`: the same document, one axis) on `task_id`
    (a track's profile task; default `profile_task`) with `policy` and return its profile
    document; `ValueError` if it does not fit the task,
    `RuntimeError` if an episode is lost (worker died twice)."""
    task_id = task_id or profile_task(policy)
    if task_id is None or policy.mismatch(task_id) is not None:
        tasks = ", ".join(track.profiled_on for track in TRACKS.values())
        raise ValueError(f"{policy.name} fits none of the profile's tasks ({tasks})")
    tasks = [task for _, _, task in protocol.specs(task_id, policy.height_scan)]
    played = play_tasks(
        policy, tasks, protocol.episodes, workers, backend, address, False, on_result
    )
    if played.missing:
        raise RuntimeError(f"{policy.name}: profile episodes lost (worker died twice)")
    records = [[episode.record() for episode in episodes] for episodes in played.episodes]
    return profile_document(policy.record(), task_id, policy.height_scan, records, protocol)


def profile_document(
    policy: dict[str, Any],
    task_id: str,
    height_scan: bool,
    records: Sequence[Sequence[dict[str, Any]]],
    protocol: Protocol = PROTOCOL,
) -> dict[str, Any]:
    """The profile document of `policy` (its record) on `task_id`, from each point's
    episode records (in `protocol.specs` order): everything else in it is computed from
    them."""
    points = protocol.specs(task_id, height_scan)
    axes: dict[str, list[dict[str, Any]]] = {}
    for (axis, value, task), point_records in zip(points, records, strict=True):
        episodes = [PlayedEpisode.from_record(record) for record in point_records]
        axes.setdefault(axis, []).append(
            {
                "value": value,
                "fingerprint": task.fingerprint,
                "seeds": [episode.seed for episode in episodes],
                "aggregate": aggregate(task, episodes),
                "episodes": [episode.record() for episode in episodes],
            }
        )
    blocks = [
        {"axis": axis, "unit": unit(axis, [task_id]), "points": rows, **robustness(rows)}
        for axis, rows in axes.items()
    ]
    return {
        "schema": SCHEMA,
        "bbbench_version": bbbench.__version__,
        "harness_version": HARNESS_VERSION,
        "policy": policy,
        "protocol": protocol.record(task_id),
        **({"height_scan": True} if height_scan else {}),
        "axes": blocks,
        "robustness": summary(blocks),
    }


def summary(axes: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The profile's two figures: the mean of the axes' robustness scores, and the least
    point of all (with its axis and value)."""
    worst = min(axes, key=lambda block: block["worst_case"])
    return {
        "score": total(block["score"] for block in axes) / len(axes),
        "worst_case": worst["worst_case"],
        "worst_axis": worst["axis"],
        "worst_value": worst["worst_value"],
    }


def stored_records(document: dict[str, Any]) -> list[list[dict[str, Any]]]:
    """Each point's episode records, in `Protocol.specs` order."""
    return [point["episodes"] for block in document["axes"] for point in block["points"]]

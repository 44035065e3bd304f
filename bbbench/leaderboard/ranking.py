"""From scored runs to the leaderboard document: each track's methods, ranked.

A method is its runs (`bbbench.leaderboard.submissions.Method`), and the board
treats them as rliable treats runs (`bbbench.evaluation.stats.Runs`): a run's
score on a task is its mean normalized score over every evaluation episode; a
method's is over runs x tasks, with a two-level bootstrap interval; P(X > Y)
compares runs. A track ranks the methods its submission names that play every one
of its tasks (a learned method with at least `RANKED_RUNS` runs), and a rank
counts the methods that beat it: ranks do not chain. Nothing here looks at a
policy or an env.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from importlib import metadata as package_metadata
from typing import Any

import numpy as np

import bbbench
from bbbench.evaluation import machine, stats
from bbbench.evaluation.results import HARNESS_VERSION, normalized
from bbbench.evaluation.team_sizes import sizes_file, trained_size
from bbbench.leaderboard.board import Board, Scored, inputs_key, profile_file, seeds_hash
from bbbench.leaderboard.submissions import Method, SubmissionError
from bbbench.policies import classical_controller
from bbbench.tasks.suite import spec
from bbbench.tasks.tracks import TRACKS

SCHEMA = "bbbench-leaderboard/2"
SATURATED = 0.95  # a task the classical controller and most methods score this on is solved
RANK_RULE = (
    "a track ranks the methods its submission names that play every one of its tasks (a "
    f"learned method with at least {stats.RANKED_RUNS} runs; a controller is one run); a "
    "method's rank is 1 plus the number of ranked methods whose P(other > it) has its 95% "
    "interval above 0.5, so ranks do not chain; the others are listed, unranked, with why"
)
SATURATION_RULE = (
    f"a task on which the track's classical controller and more than half of its methods "
    f"score at least {SATURATED} is saturated: it stays on the board as a check and leaves "
    f"the track's overall"
)


def leaderboard_document(
    methods: Sequence[Method], scored: Sequence[Scored], board: Board
) -> dict[str, Any]:
    """The leaderboard: per track, its methods ranked from their runs' results documents."""
    runs = {entry.run.slug: entry for entry in scored}
    for method in methods:
        for name in method.metadata["tracks"]:
            if name in TRACKS and not _played(method, runs, board.track_tasks(name)):
                raise SubmissionError(
                    f"{method.folder}: names the {TRACKS[name].label} track, but plays none of "
                    f"its tasks on this board; name the tracks whose tasks it plays"
                )
    return {
        "schema": SCHEMA,
        "bbbench_version": bbbench.__version__,
        "harness_version": HARNESS_VERSION,
        "pybullet_version": package_metadata.version("pybullet"),
        "statistics": {
            **stats.method(),
            "method": stats.METHOD_RULE,
            "ranking": RANK_RULE,
            "saturation": SATURATION_RULE,
        },
        "platform": machine.record(),
        "tracks": [
            _track(track, methods, runs, board) for track in TRACKS if board.track_tasks(track)
        ],
    }


def _played(method: Method, runs: dict[str, Scored], task_ids: Sequence[str]) -> list[str]:
    """Of `task_ids`, those every run of `method` played."""
    played = [{block["task"] for block in runs[run.slug].results["tasks"]} for run in method.runs]
    return [task_id for task_id in task_ids if all(task_id in tasks for tasks in played)]


@dataclasses.dataclass
class _Listed:
    """A method on a track: its runs' episode scores per task it played."""

    method: Method
    scored: list[Scored]  # its runs', in order
    played: list[str]  # the track's tasks every run played
    scores: dict[str, np.ndarray]  # task -> (runs, episodes) normalized scores
    runs: stats.Runs | None = None  # over the track's overall tasks, if it played them all
    unranked: str | None = None
    beaten_by: list[str] = dataclasses.field(default_factory=list)

    @property
    def slug(self) -> str:
        return self.method.slug

    @property
    def point(self) -> float:
        return -np.inf if self.runs is None else self.runs.point()


def episode_scores(documents: Sequence[dict[str, Any]], task_id: str) -> np.ndarray:
    """(runs, episodes): each run's normalized score of each episode of `task_id`, from
    the runs' results documents."""
    return np.array(
        [
            [normalized(record["return"], spec(task_id)) for record in block["episodes"]]
            for document in documents
            for block in document["tasks"]
            if block["task"] == task_id
        ]
    )


def _listed(method: Method, runs: dict[str, Scored], task_ids: Sequence[str]) -> _Listed:
    scored = [runs[run.slug] for run in method.runs]
    played = _played(method, runs, task_ids)
    documents = [entry.results for entry in scored]
    scores = {
        task_id: episode_scores(documents, task_id)
        for task_id in played
        if spec(task_id).random_return is not None
    }
    return _Listed(method, scored, played, scores)


def _track(
    track: str, methods: Sequence[Method], runs: dict[str, Scored], board: Board
) -> dict[str, Any]:
    task_ids = board.track_tasks(track)
    ranked = board.ranked(track)
    listed = [_listed(m, runs, task_ids) for m in methods if track in m.metadata["tracks"]]
    task_blocks = {m.slug: _task_blocks(m) for m in listed}
    saturated = [t for t in ranked if _saturated(t, listed, task_blocks)]
    counted = [t for t in ranked if t not in saturated and spec(t).random_return is not None]
    for member in listed:
        if counted and all(t in member.scores for t in counted):
            member.runs = stats.Runs(
                tuple(member.scores[t] for t in counted), seed=stats.method_seed(member.slug)
            )
        member.unranked = _why_unranked(member, ranked)
    contenders = [m for m in listed if m.unranked is None]
    versus = {}
    for member in contenders:
        for other in contenders:
            if other is not member:
                point, (low, high) = stats.run_improvement(other.runs, member.runs)
                versus[other.slug, member.slug] = (point, low, high)
                if low > 0.5:
                    member.beaten_by.append(other.slug)
    rank = stats.ranks({m.slug: m.beaten_by for m in contenders})
    order = sorted(contenders, key=lambda m: (rank[m.slug], -m.point, m.slug))
    order += sorted((m for m in listed if m.unranked), key=lambda m: (-m.point, m.slug))
    return {
        "track": track,
        "title": TRACKS[track].title,
        "tasks": [
            {
                "task": task_id,
                "version": spec(task_id).version,
                "fingerprint": spec(task_id).fingerprint,
                "eval_seeds_sha256": seeds_hash(board.seeds(task_id)),
                "episodes": len(board.seeds(task_id)),
                "ranked": task_id in ranked,
                "saturated": task_id in saturated,
                "overall": task_id in counted,
            }
            for task_id in task_ids
        ],
        "methods": [
            {
                "rank": rank.get(member.slug),
                "unranked": member.unranked,
                "slug": member.slug,
                "submission": member.method.metadata,
                "height_scan": any(
                    block.get("height_scan", False)
                    for entry in member.scored
                    for block in entry.results["tasks"]
                ),
                "tasks": task_blocks[member.slug],
                "overall": _overall(member, counted),
                "robustness": _method_robustness(member, track),
                "team_sizes": _method_sizes(member, track),
                "beaten_by": sorted(member.beaten_by),
                "versus_next": _next(member, order, versus),
                "runs": [_run(entry, member, track, board, task_ids) for entry in member.scored],
            }
            for member in order
        ],
    }


def _task_blocks(member: _Listed) -> dict[str, Any]:
    """Per task it played: the method's score over runs, with its two-level interval, and
    its runs' success rate."""
    blocks = {}
    for task_id in member.played:
        aggregates = [
            block["aggregate"]
            for entry in member.scored
            for block in entry.results["tasks"]
            if block["task"] == task_id
        ]
        block = {
            "runs": len(aggregates),
            "episodes": aggregates[0]["episodes"],
            "success_rate": float(np.mean([a["success_rate"] for a in aggregates])),
        }
        if task_id in member.scores:
            runs = stats.Runs((member.scores[task_id],), seed=stats.method_seed(member.slug))
            block["normalized_score"] = runs.point()
            block["normalized_ci"] = list(runs.interval())
        blocks[task_id] = block
    return blocks


def _saturated(
    task_id: str, listed: Sequence[_Listed], task_blocks: dict[str, dict[str, Any]]
) -> bool:
    """`SATURATION_RULE`: the task's classical controller and most methods at `SATURATED`."""
    scores = {
        m.slug: task_blocks[m.slug][task_id]["normalized_score"]
        for m in listed
        if "normalized_score" in task_blocks[m.slug].get(task_id, {})
    }
    classical = [
        m.slug
        for m in listed
        if m.slug in scores and m.method.metadata.get("builtin") == classical_controller(task_id)
    ]
    solved = [slug for slug, score in scores.items() if score >= SATURATED]
    return bool(classical) and scores[classical[0]] >= SATURATED and 2 * len(solved) > len(scores)


def _why_unranked(member: _Listed, ranked: Sequence[str]) -> str | None:
    missing = [t for t in ranked if t not in member.played]
    if missing:
        return f"plays {len(ranked) - len(missing)} of the track's {len(ranked)} tasks"
    runs = len(member.method.runs)
    if member.method.learned and runs < stats.RANKED_RUNS:
        return f"{runs} run{'s' * (runs != 1)}; a learned method ranks from {stats.RANKED_RUNS}"
    return None


def _overall(member: _Listed, counted: Sequence[str]) -> dict[str, Any]:
    if member.runs is None:
        return {"tasks": 0}
    return {
        "tasks": len(counted),
        "runs": member.runs.runs,
        "statistic": "IQM" if member.runs.runs >= stats.IQM_RUNS else "mean",
        "normalized_score": member.runs.point(),
        "normalized_ci": list(member.runs.interval()),
    }


def _next(
    member: _Listed, order: Sequence[_Listed], versus: dict[tuple[str, str], tuple]
) -> dict[str, Any] | None:
    """P(it > the next ranked method), with its interval."""
    ranked = [m for m in order if m.unranked is None]
    if member not in ranked or ranked.index(member) + 1 == len(ranked):
        return None
    below = ranked[ranked.index(member) + 1]
    point, low, high = versus[member.slug, below.slug]
    return {"slug": below.slug, "probability_of_improvement": point, "ci": [low, high]}


def _run(
    entry: Scored, member: _Listed, track: str, board: Board, task_ids: Sequence[str]
) -> dict[str, Any]:
    blocks = {block["task"]: block for block in entry.results["tasks"]}
    return {
        "slug": entry.run.slug,
        "training_seed": entry.run.record["training_seed"],
        "inputs": inputs_key(entry.run, board),
        "record": entry.run.record,
        "policy": entry.results["policy"],
        "results": f"results/{entry.run.slug}.json",
        "tasks": {t: blocks[t]["aggregate"] for t in task_ids if t in blocks},
        "robustness": _run_robustness(entry, track),
        "team_sizes": _sizes(entry, track),
    }


def _run_robustness(entry: Scored, track: str) -> dict[str, Any] | None:
    """A run's profile on the board: its figures and where its profile document is (each
    point is there; the method's entry draws the axes over its runs)."""
    profile = _robustness(entry, track)
    return None if profile is None else {k: v for k, v in profile.items() if k != "axes"}


def _robustness(entry: Scored, track: str) -> dict[str, Any] | None:
    """A run's profile on `track` as the board shows it: its two figures, and per axis the
    normalized score at each grid value (None: not profiled there)."""
    document = entry.profiles.get(track)
    if document is None:
        return None
    return {
        **document["robustness"],
        "task": document["protocol"]["task"],
        "profile": f"results/{profile_file(entry.run.slug, track)}",
        "axes": {
            block["axis"]: {
                "score": block["score"],
                "worst_case": block["worst_case"],
                "points": [
                    [
                        point["value"],
                        point["aggregate"]["normalized_score"],
                        *point["aggregate"]["normalized_ci"],
                    ]
                    for point in block["points"]
                ],
            }
            for block in document["axes"]
        },
    }


def _method_robustness(member: _Listed, track: str) -> dict[str, Any] | None:
    """The method's profile: the mean of its runs' scores, the least of their worst cases,
    and per axis and grid value the runs' mean score, between their least and greatest."""
    profiles = [_robustness(entry, track) for entry in member.scored]
    if any(profile is None for profile in profiles):
        return None
    axes = {}
    for axis in profiles[0]["axes"]:
        points = np.array([p["axes"][axis]["points"] for p in profiles])  # (runs, values, 4)
        axes[axis] = {
            "score": float(np.mean([p["axes"][axis]["score"] for p in profiles])),
            "worst_case": float(min(p["axes"][axis]["worst_case"] for p in profiles)),
            "points": _over_runs(points, float),
        }
    worst = min(profiles, key=lambda profile: profile["worst_case"])
    return {
        "score": float(np.mean([p["score"] for p in profiles])),
        "worst_case": worst["worst_case"],
        "worst_axis": worst["worst_axis"],
        "worst_value": worst["worst_value"],
        "task": profiles[0]["task"],
        "runs": len(profiles),
        "axes": axes,
    }


def _sizes(entry: Scored, track: str) -> dict[str, Any] | None:
    """A run's team-size profile on `track` as the board shows it: the normalized score
    and its interval at each size, and the size its method trained with (None: not
    profiled on this track)."""
    document = entry.sizes.get(track)
    if document is None:
        return None
    (block,) = document["axes"]
    task_id = document["protocol"]["task"]
    return {
        "task": task_id,
        "trained_with": trained_size(entry.run.record, task_id),
        "profile": f"results/{sizes_file(entry.run.slug, track)}",
        "points": [
            [
                point["value"],
                point["aggregate"]["normalized_score"],
                *point["aggregate"]["normalized_ci"],
            ]
            for point in block["points"]
        ],
    }


def _method_sizes(member: _Listed, track: str) -> dict[str, Any] | None:
    """The method's team-size profile: at each size its runs' mean score, between their
    least and greatest, and the size its runs trained with (None where they differ)."""
    runs = [_sizes(entry, track) for entry in member.scored]
    if not runs or any(run is None for run in runs):
        return None
    points = np.array([run["points"] for run in runs])  # (runs, sizes, 4)
    trained = {run["trained_with"] for run in runs}
    return {
        "task": runs[0]["task"],
        "trained_with": trained.pop() if len(trained) == 1 else None,
        "runs": len(runs),
        "points": _over_runs(points, int),
    }


def _over_runs(points: np.ndarray, value: Callable[[Any], Any]) -> list[list[Any]]:
    """A method's profile from its runs' (runs, grid values, 4) `points`: per grid value,
    [the value (as `value` makes it), the runs' mean score, their least, their greatest]."""
    return [
        [
            value(points[0, i, 0]),
            float(points[:, i, 1].mean()),
            float(points[:, i, 1].min()),
            float(points[:, i, 1].max()),
        ]
        for i in range(points.shape[1])
    ]


def performance_profile(
    results: Sequence[dict[str, Any]], ranked: Sequence[str], thresholds: np.ndarray
) -> np.ndarray:
    """rliable's score distribution of a method: for each threshold tau, the fraction of
    episodes with normalized score above tau, averaged over its runs and the ranked tasks
    they played."""
    fractions = []
    for document in results:
        for block in document["tasks"]:
            task_id = block["task"]
            if task_id in ranked and spec(task_id).random_return is not None:
                (scores,) = episode_scores([document], task_id)
                fractions.append((scores[:, None] > thresholds[None, :]).mean(axis=0))
    return np.mean(fractions, axis=0) if fractions else np.zeros_like(thresholds)

"""What a leaderboard plays, and playing it.

Two steps, kept apart. `score` plays each run's episodes with the shipped
harness (`bbbench.evaluation.evaluate`) and returns its results document, the
`bbbench eval --json` format, reusing stored task results whose key still
matches. `bbbench.leaderboard.ranking` ranks methods from those results documents
alone: nothing in it looks at a policy or an env.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Callable, Sequence
from importlib import metadata as package_metadata
from pathlib import Path
from typing import Any

import bbbench
from bbbench.evaluation import PlayedEpisode, evaluate, results_document
from bbbench.evaluation.profile import EPISODES_OF as PROFILES_OF
from bbbench.evaluation.profile import (
    PROTOCOL,
    Protocol,
    profile,
    profile_document,
    stored_records,
)
from bbbench.evaluation.results import EPISODES_OF, HARNESS_VERSION, read
from bbbench.evaluation.team_sizes import SUFFIX as SIZES_SUFFIX
from bbbench.evaluation.team_sizes import TEAM_SIZES, TeamSizes, sizes_file
from bbbench.leaderboard.submissions import Run, SubmissionError
from bbbench.policies import Policy
from bbbench.portable import total
from bbbench.tasks.spec import TaskSpec
from bbbench.tasks.suite import list_tasks, spec
from bbbench.tasks.tracks import TRACKS, Track, track_of

PROFILE_SUFFIX = ".profile.json"  # results/<slug>.<track>.profile.json: a robustness profile


def profile_file(slug: str, track: str) -> str:
    """The name of an entry's robustness profile on a track, in the results folder."""
    return f"{slug}.{track}{PROFILE_SUFFIX}"


def is_profile(name: str) -> bool:
    """Whether a file of the results folder is a profile document (robustness, or team
    sizes), not a run's results document."""
    return name.endswith((PROFILE_SUFFIX, SIZES_SUFFIX))


class BuildError(RuntimeError):
    """The board cannot be completed (an episode whose worker died twice)."""


@dataclasses.dataclass(frozen=True)
class Board:
    """What a leaderboard plays: its tasks (default: the latest version of each task of the
    suite; a superseded version leaves the board, its last numbers stay in git history) and
    the first `episodes` eval seeds of each (default: all of them)."""

    tasks: tuple[str, ...] = dataclasses.field(
        default_factory=lambda: tuple(list_tasks(latest=True))
    )
    episodes: int | None = None
    # The robustness profile every entry gets (None: none).
    profile: Protocol | None = PROTOCOL
    # The team-size profile every entry on a track that declares one gets (None: none).
    team_sizes: TeamSizes | None = TEAM_SIZES

    def __post_init__(self) -> None:
        for task_id in self.tasks:  # a task no track ranks would silently leave the board
            track_of(spec(task_id))

    def seeds(self, task_id: str) -> list[int]:
        return list(spec(task_id).eval_seeds[: self.episodes])

    def track_tasks(self, track: str) -> list[str]:
        """The track's tasks: by name, each name's versions newest first."""
        tasks = [t for t in self.tasks if TRACKS[track].holds(spec(t))]
        return sorted(tasks, key=lambda t: (spec(t).name, -spec(t).version))

    def ranked(self, track: str) -> list[str]:
        """The latest version of each task of the track: the ones the ranking uses."""
        latest: dict[str, str] = {}
        for task_id in self.track_tasks(track):
            latest.setdefault(spec(task_id).name, task_id)
        return list(latest.values())


@dataclasses.dataclass(frozen=True)
class Scored:
    """A run, its results document and its robustness profiles, one for each track it is
    on whose profile task it fits (track name -> profile document), and its team-size
    profiles on those of the tracks that declare one (`sizes`, the same kind of
    document); `played`: episodes played to get them (the rest came from stored results)."""

    run: Run
    results: dict[str, Any]
    played: int
    profiles: dict[str, dict[str, Any]] = dataclasses.field(default_factory=dict)
    sizes: dict[str, dict[str, Any]] = dataclasses.field(default_factory=dict)


def inputs_key(run: Run, board: Board) -> str:
    """SHA-256 of everything a run's numbers depend on: its method's and its own files, the
    harness's, bbbench's and the simulator's versions, the board's tasks (fingerprint and
    seeds) and the profiles' protocols. The board records it per run (`inputs`), so that
    a check finds a changed or new run without the repository's history."""
    files = [*run.files, run.policy_file, run.normalization_file]
    inputs = {
        "files": {
            path.name: hashlib.sha256(path.read_bytes()).hexdigest()
            for path in files
            if path is not None and path.is_file()
        },
        "harness_version": HARNESS_VERSION,
        "bbbench_version": bbbench.__version__,
        "pybullet_version": package_metadata.version("pybullet"),
        "tasks": {t: [spec(t).fingerprint, seeds_hash(board.seeds(t))] for t in board.tasks},
        "profile": None
        if board.profile is None
        else [board.profile.record(track.profiled_on) for track in TRACKS.values()],
        "team_sizes": None
        if board.team_sizes is None
        else [
            board.team_sizes.record(track.profiled_on)
            for track in TRACKS.values()
            if track.team_sizes
        ],
    }
    return hashlib.sha256(json.dumps(inputs, sort_keys=True).encode()).hexdigest()


def score(
    runs: Sequence[Run],
    board: Board,
    stored: Path | None,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
    on_episodes: Callable[[int], None] | None = None,
    keys: dict[str, str | None] | None = None,
) -> list[Scored]:
    """Each run's results document on the board's tasks it fits, and its profiles.
    With `stored` (the folder of results documents, `<root>/results`), a task whose stored
    result has the same key (policy file's SHA-256 and statistics, task fingerprint, seeds,
    harness and bbbench versions) is not played again, nor a profile of the same policy
    and protocol; with `keys` (slug -> the inputs key the board recorded), an entry's
    stored results are used only when its key is today's (`inputs_key`)."""
    scored = []
    for run in runs:
        policy = run.load_policy()
        if keys is not None and keys.get(run.slug) != inputs_key(run, board):
            stored_here = None  # changed or new since its results were stored: play it all
        else:
            stored_here = stored
        task_ids = [t for t in board.tasks if policy.mismatch(t) is None]
        if not task_ids:
            raise SubmissionError(
                f"{run.policy_file or run.folder}: the policy "
                f"({policy.spaces_text()}) fits none of the board's tasks"
            )
        reused = (
            {} if stored_here is None else _stored_episodes(stored_here, run.slug, policy, board)
        )
        pending = [t for t in task_ids if t not in reused]
        played: dict[str, list[PlayedEpisode]] = {}
        on_result = None if on_episodes is None else lambda n, _: on_episodes(n)
        if pending:
            evaluation = evaluate(
                policy,
                pending,
                episodes=board.episodes,
                workers=workers,
                backend=backend,
                address=address,
                on_result=on_result,
            )
            if evaluation.missing:
                lost = ", ".join(f"{task} seed {seed}" for task, seed in evaluation.missing)
                raise BuildError(f"{run.slug}: episodes lost (worker died twice): {lost}")
            played = _episodes(evaluation.document)
        results = {t: reused[t] if t in reused else played[t] for t in task_ids}
        protocol, profiles, profiled = board.profile, {}, 0
        tracks = [] if protocol is None else _profiled_tracks(policy, task_ids)
        tracks = [track for track in tracks if track.name in run.method["tracks"]]
        sizes: dict[str, dict[str, Any]] = {}
        # The run's profiles on each track its method is ranked on: robustness, and team
        # sizes where the track declares them.
        jobs = [(protocol, profile_file(run.slug, t.name), t, profiles) for t in tracks]
        if board.team_sizes is not None:
            jobs += [
                (board.team_sizes, sizes_file(run.slug, t.name), t, sizes)
                for t in tracks
                if t.team_sizes
            ]
        for kind, file_name, track, kept in jobs:
            document = None
            if stored_here is not None:
                document = _stored_profile(stored_here, file_name, track, policy, kind)
            if document is None:
                document = profile(
                    policy, workers, backend, address, on_result, kind, track.profiled_on
                )
                profiled += total(len(records) for records in stored_records(document))
            kept[track.name] = document
        scored.append(
            Scored(
                run,
                results_document(policy, results),
                total(len(played[t]) for t in pending) + profiled,
                profiles,
                sizes,
            )
        )
    return scored


def _profiled_tracks(policy: Policy, task_ids: Sequence[str]) -> list[Track]:
    """The tracks an entry playing `task_ids` is on whose profile task `policy` fits."""
    return [
        track
        for track in TRACKS.values()
        if any(track.holds(spec(task_id)) for task_id in task_ids)
        and policy.mismatch(track.profiled_on) is None
    ]


def _stored_profile(
    folder: Path, name: str, track: Track, policy: Policy, protocol: Protocol | TeamSizes
) -> dict[str, Any] | None:
    """`folder/<name>` (`<slug>.<track>.profile.json`, or `.sizes.json`) when it is today's
    profile of `policy` on the track: the same policy, protocol and versions, and every
    point the spec it played then (a board built before profiles were per track kept
    one, `<slug>.profile.json`: it is today's when its protocol is the track's)."""
    try:
        path = folder / name
        per_track = f".{track.name}{PROFILE_SUFFIX}"
        if not path.is_file() and name.endswith(per_track):  # before per-track profiles
            path = folder / f"{name.removesuffix(per_track)}{PROFILE_SUFFIX}"
        old = read(path)
        task_id = track.profiled_on
        if (
            old["schema"] not in PROFILES_OF
            or old["harness_version"] != HARNESS_VERSION
            or old["bbbench_version"] != bbbench.__version__
            or not same_policy(old["policy"], policy.record())
            or old["protocol"] != protocol.record(task_id)
        ):
            return None
        points = [point for block in old["axes"] for point in block["points"]]
        specs = protocol.specs(task_id, policy.height_scan)
        seeds = list(spec(task_id).eval_seeds[: protocol.episodes])
        if len(points) != len(specs) or any(
            point["fingerprint"] != task.fingerprint or point["seeds"] != seeds
            for point, (_, _, task) in zip(points, specs, strict=False)
        ):
            return None
        records = stored_records(old)
        if not all(records_current(spec(task_id), point) for point in records):
            return None
        return profile_document(policy.record(), task_id, policy.height_scan, records, protocol)
    except (OSError, ValueError, KeyError, TypeError):  # absent or not ours: play again
        return None


def _episodes(document: dict[str, Any]) -> dict[str, list[PlayedEpisode]]:
    return {
        block["task"]: [PlayedEpisode.from_record(record) for record in block["episodes"]]
        for block in document["tasks"]
    }


def _stored_episodes(
    folder: Path, slug: str, policy: Policy, board: Board
) -> dict[str, list[PlayedEpisode]]:
    """The tasks of `folder/<slug>.json` whose key matches today's: their episodes."""
    try:
        old = read(folder / f"{slug}.json")
        if (
            old["schema"] not in EPISODES_OF
            or old["harness_version"] != HARNESS_VERSION
            or old["bbbench_version"] != bbbench.__version__
            or not same_policy(old["policy"], policy.record())
            or old["deterministic"] != (not policy.random_actions)
        ):
            return {}
        reusable = {}
        for block in old["tasks"]:
            task = spec(block["task"]).with_height_scan(policy.height_scan)
            seeds = board.seeds(task.id)
            episodes = [PlayedEpisode.from_record(record) for record in block["episodes"]]
            if (
                task.id in board.tasks
                and block["fingerprint"] == task.fingerprint
                and block["seeds"] == seeds
                and [episode.seed for episode in episodes] == seeds
                and records_current(task, block["episodes"])
            ):
                reusable[task.id] = episodes
        return reusable
    except (OSError, ValueError, KeyError, TypeError):  # absent or not ours: play again
        return {}


def records_current(task: TaskSpec, records: list[dict[str, Any]]) -> bool:
    """Whether stored episode records hold what today's do: each of the scenario's
    metrics, and on a team task each episode's cause (or its failure). Records made
    before a metric or the causes were recorded are played again."""
    metrics = task.scenario_class.metrics
    if not all(metric in record for record in records for metric in metrics):
        return False
    if not task.scenario_class.team:
        return True
    return all("cause" in record or record["failure"] is not None for record in records)


def same_policy(recorded: dict[str, Any], today: dict[str, Any]) -> bool:
    """Whether a stored record's policy plays as `today`'s: the same record but for its
    `name`, a label that plays no part (documents made again from stored episodes take
    today's name)."""
    return {**recorded, "name": None} == {**today, "name": None}


def seeds_hash(seeds: Sequence[int]) -> str:
    """SHA-256 of the seeds as a JSON list: '[2147483648, ...]'."""
    return hashlib.sha256(json.dumps(list(seeds)).encode()).hexdigest()

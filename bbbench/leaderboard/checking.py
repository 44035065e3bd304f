"""`bbbench leaderboard check`: every number of the board computed again from its records and
compared byte for byte, changed runs re-scored in full, the others spot-checked by
replaying episodes drawn at random (or, with `full`, every episode played again)."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from collections.abc import Callable
from importlib import metadata as package_metadata
from pathlib import Path
from typing import Any

import numpy as np

from bbbench.evaluation import machine
from bbbench.evaluation.harness import play_draws
from bbbench.leaderboard.board import Board, Scored
from bbbench.leaderboard.diff import differences
from bbbench.leaderboard.generation import DEFAULT_BOARD, DOCUMENT, SUBMISSIONS, generate
from bbbench.leaderboard.page import is_figure
from bbbench.leaderboard.submissions import RUN_FILE, SUBMISSION_FILE, Method, read_methods
from bbbench.tasks.suite import spec

# Episodes the default check replays of the unchanged entries, drawn afresh at every run:
# a fixed budget for the whole board, whatever its size, shared evenly by the entries (by
# a random one each when there are more entries than episodes) and drawn uniformly from
# each entry's records (its tasks' and its profiles' points: robustness, team sizes). An
# entry whose records are all forged is caught at every run while the board has at most
# SPOT_BUDGET entries (with probability SPOT_BUDGET / entries beyond); one forged episode
# among an entry's n records, with probability k / n for the entry's k draws
# (docs/performance.md gives the figures for the repository's board).
SPOT_BUDGET = 1000
# The figures' bytes are the same for one matplotlib only: the version constraints.txt pins.
PLOTTING_STACK = {"matplotlib": "3.11.2"}


@dataclasses.dataclass(frozen=True)
class Checked:
    """What `check` found: readable problems (none: the board is exact), and what it did."""

    problems: list[str]
    entries: int  # runs
    tasks: int
    episodes: int  # episodes played: every episode of the re-scored entries, and the spot-checks
    seconds: float
    rescored: list[str] = dataclasses.field(default_factory=list)  # slugs played in full
    spot_checked: int = 0  # episodes replayed by the spot-check
    notes: list[str] = dataclasses.field(default_factory=list)  # what was skipped, and why


def check(
    root: str | Path,
    board: Board = DEFAULT_BOARD,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
    on_episodes: Callable[[int], None] | None = None,
    full: bool = False,
    spot: int = SPOT_BUDGET,
    rng: np.random.Generator | None = None,
) -> Checked:
    """Check the board in `root` against its submissions.

    What can be told without playing is told first, and then nothing is played: a
    missing board, a task whose fingerprint changed, an entry whose submission is gone.
    Then, by default:

    - every aggregate, rank and generated file is computed again from the per-episode
      records and compared byte for byte (a tampered aggregate is always caught);
    - every entry whose inputs changed (`inputs_key`: its files, the versions, the tasks,
      the protocol) or that is new is re-scored in full, and compared the same way;
    - `spot` episodes of the other entries in all, shared evenly by them and drawn from
      `rng` (default: fresh at every run), are replayed and compared with their records.

    With `full`, every episode of every entry is played again (the check before this
    one). The figures are compared only under the pinned plotting stack
    (`PLOTTING_STACK`); otherwise a note says they were skipped.
    """
    began = time.perf_counter()
    root = Path(root)
    methods = read_methods(root / SUBMISSIONS)
    runs = [run for method in methods for run in method.runs]
    try:
        recorded = json.loads((root / DOCUMENT).read_bytes())
    except (OSError, ValueError) as error:
        problem = f"{root / DOCUMENT}: cannot be read ({error}): run `bbbench leaderboard build`"
        return Checked([problem], len(runs), 0, 0, time.perf_counter() - began)
    problems, changed = _stale_inputs(root, recorded, methods, board)
    if problems:
        return Checked(problems, len(runs), len(board.tasks), 0, time.perf_counter() - began)
    play = {"workers": workers, "backend": backend, "address": address}
    keys = {run["slug"]: run.get("inputs") for run in _recorded_runs(recorded).values()}
    built = generate(root, board, cache=not full, on_episodes=on_episodes, keys=keys, **play)
    notes = []
    stack = plotting_stack()
    skipped = [] if stack == PLOTTING_STACK else [name for name in built.files if is_figure(name)]
    if skipped:
        notes.append(
            f"{len(skipped)} figures not compared: they are drawn byte for byte by "
            f"{_versions(PLOTTING_STACK)} only, and this is {_versions(stack)}"
        )
    problems = changed + differences(root, built.files, skip=skipped)
    rescored = [entry.run.slug for entry in built.scored if entry.played]
    spot_checked = 0
    if not full and not problems:
        others = [entry for entry in built.scored if not entry.played]
        rng = np.random.default_rng() if rng is None else rng
        problems, spot_checked = _spot_check(others, board, spot, rng, on_episodes, play)
    made_on, here = recorded.get("platform"), machine.record()
    if made_on != here:
        built_on = f"the board was built on {machine.described(made_on)}"
        if problems:
            problems.insert(
                0,
                f"this check ran on {machine.described(here)}; {built_on}. What differs "
                f"(another build, or another board):",
            )
        else:
            notes.append(
                f"{built_on}; this check ran on {machine.described(here)}, and reproduces it"
            )
    return Checked(
        problems,
        len(runs),
        len(board.tasks),
        built.played + spot_checked,
        time.perf_counter() - began,
        rescored,
        spot_checked,
        notes,
    )


def plotting_stack() -> dict[str, str | None]:
    found = {}
    for package in PLOTTING_STACK:
        try:
            found[package] = package_metadata.version(package)
        except package_metadata.PackageNotFoundError:
            found[package] = None
    return found


def _versions(stack: dict[str, str | None]) -> str:
    return ", ".join(f"{name} {version or '(none)'}" for name, version in stack.items())


def _spot_check(
    entries: list[Scored],
    board: Board,
    spot: int,
    rng: np.random.Generator,
    on_episodes: Callable[[int], None] | None,
    play: dict[str, Any],
) -> tuple[list[str], int]:
    """Replay `spot` episodes of `entries` in all, drawn from `rng`, on one pool of
    workers: each entry's share (`spot` split evenly; one each for `spot` entries drawn
    at random when there are more), drawn uniformly from its records. The records that
    differ from the replay, and how many were replayed."""
    shares = _shares(len(entries), spot, rng)
    draws = []  # (policy, spec, seed, slug, the recorded episode)
    for entry, share in zip(entries, shares, strict=True):
        if share == 0:
            continue
        policy = entry.run.load_policy()
        records = [  # (spec, the recorded episode), every task's and profile point's
            (spec(block["task"]).with_height_scan(policy.height_scan), record)
            for block in entry.results["tasks"]
            for record in block["episodes"]
        ]
        for protocol, documents in (
            (board.profile, entry.profiles),
            (board.team_sizes, entry.sizes),
        ):
            for document in documents.values():
                task_id = document["protocol"]["task"]
                points = [p for block in document["axes"] for p in block["points"]]
                records += [
                    (task, record)
                    for (_, _, task), point in zip(
                        protocol.specs(task_id, policy.height_scan), points, strict=True
                    )
                    for record in point["episodes"]
                ]
        drawn = rng.choice(len(records), min(share, len(records)), replace=False)
        draws += [
            (policy, records[i][0], records[i][1]["seed"], entry.run.slug, records[i][1])
            for i in sorted(int(i) for i in drawn)
        ]
    played = play_draws(
        [(policy, task, seed) for policy, task, seed, _, _ in draws],
        on_result=None if on_episodes is None else lambda n, _: on_episodes(n),
        **play,
    )
    differ = []
    for (_, task, seed, slug, record), episode in zip(draws, played, strict=True):
        replay = None if episode is None else episode.record()
        if replay != record:
            differ.append((f"{slug}: {_stratum(task)} seed {seed}", record, replay))
    return ([] if not differ else [_episodes_differ(differ, len(draws))]), len(draws)


def _episodes_differ(
    differ: list[tuple[str, dict[str, Any], dict[str, Any] | None]], replayed: int, shown: int = 3
) -> str:
    """One line for the replayed episodes that differ from their records: how many, by
    how much at most (return, length), and the first few."""
    returns = [
        abs(replay["return"] - record["return"])
        for _, record, replay in differ
        if replay is not None
    ]
    by = f", returns by at most {max(returns):.3g}" if returns else ""
    first = "; ".join(
        f"{where}: recorded {_said(record)}, replayed {_said(replay)}"
        for where, record, replay in differ[:shown]
    )
    return (
        f"{len(differ)} of {replayed} replayed episodes differ from their records{by} "
        f"(first: {first})"
    )


def _shares(entries: int, budget: int, rng: np.random.Generator) -> list[int]:
    """How many of `budget` episodes each of `entries` entries gets: an even split, the
    remainder one each to entries drawn at random."""
    if entries == 0:
        return []
    shares = [budget // entries] * entries
    for i in rng.choice(entries, budget % entries, replace=False):
        shares[int(i)] += 1
    return shares


def _stratum(task) -> str:
    changes = ", ".join(f"{p.keyword}={p.value:g}" for p in task.perturbations)
    return task.id + (f" ({changes})" if changes else "")


def _said(record: dict[str, Any] | None) -> str:
    if record is None:
        return "nothing (its worker died twice)"
    return f"return {record['return']!r} in {record['length']} steps"


def _recorded_runs(recorded: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The board's runs by slug, each with its method's metadata (`method`)."""
    return {
        run["slug"]: {**run, "method": method["submission"]}
        for track in recorded.get("tracks", [])
        for method in track.get("methods", [])
        for run in method["runs"]
    }


def _stale_inputs(
    root: Path, recorded: dict[str, Any], methods: list[Method], board: Board
) -> tuple[list[str], list[str]]:
    """What can be told without playing: the problems that end the check at once (the
    board's tasks, runs whose submission is gone), and the runs changed since the build
    (said beside what their full re-score finds)."""
    problems, changed = [], []
    tasks = {task["task"]: task for track in recorded.get("tracks", []) for task in track["tasks"]}
    for task_id in board.tasks:
        if task_id not in tasks:
            problems.append(f"task {task_id}: not on the board: run `bbbench leaderboard build`")
        elif tasks[task_id]["fingerprint"] != spec(task_id).fingerprint:
            problems.append(
                f"task {task_id}: its fingerprint is now {spec(task_id).fingerprint}, the board "
                f"was built with {tasks[task_id]['fingerprint']}: the task's behaviour changed "
                f"(a changed task needs a new version, -vN)"
            )
    problems += [
        f"task {task_id}: on the board, not in the suite any more"
        for task_id in tasks
        if task_id not in board.tasks
    ]
    entries = _recorded_runs(recorded)
    for method in methods:
        for run in method.runs:
            entry = entries.get(run.slug)
            if entry is None:
                changed.append(
                    f"{run.folder}: a run that is not on the board: run `bbbench leaderboard "
                    f"build` and commit what it writes"
                )
                continue
            if run.policy_file is not None:
                sha = hashlib.sha256(run.policy_file.read_bytes()).hexdigest()
                if sha != entry["policy"]["sha256"]:
                    changed.append(
                        f"{run.policy_file}: SHA-256 {sha[:16]}..., the board was built "
                        f"from {str(entry['policy']['sha256'])[:16]}...: the policy file changed"
                    )
            for path, now, then in (
                (method.folder / SUBMISSION_FILE, method.metadata, entry["method"]),
                (run.folder / RUN_FILE, run.record, entry["record"]),
            ):
                if now != then and not (path.name == RUN_FILE and run.folder == method.folder):
                    fields = sorted(key for key in {*now, *then} if now.get(key) != then.get(key))
                    changed.append(
                        f"{path}: changed since the board was built "
                        f"(field {', '.join(repr(key) for key in fields)})"
                    )
    slugs = {run.slug for method in methods for run in method.runs}
    problems += [
        f"run {slug!r}: on the board, but its folder in {root / SUBMISSIONS} is gone"
        for slug in entries
        if slug not in slugs
    ]
    return problems, list(dict.fromkeys(changed))

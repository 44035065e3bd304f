"""`bbbench leaderboard check`: rebuild the board from scratch and compare, byte for byte."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bbbench.leaderboard.board import Board
from bbbench.leaderboard.diff import differences
from bbbench.leaderboard.generation import DEFAULT_BOARD, DOCUMENT, SUBMISSIONS, generate
from bbbench.leaderboard.submissions import SUBMISSION_FILE, Submission, read_submissions
from bbbench.tasks.suite import spec


@dataclasses.dataclass(frozen=True)
class Checked:
    """What `check` found: readable problems (none: the board is exact)."""

    problems: list[str]
    entries: int
    tasks: int
    episodes: int
    seconds: float


def check(
    root: str | Path,
    board: Board = DEFAULT_BOARD,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
    on_episodes: Callable[[int], None] | None = None,
) -> Checked:
    """Rebuild the board in `root` from its submissions, from scratch (no stored
    result reused), and compare every generated file with the one checked in.

    What can be told without playing is told first, and then nothing is played: a
    missing board, a task whose fingerprint changed, a submission added or removed
    without a rebuild, a policy file or metadata changed since the build.
    """
    began = time.perf_counter()
    root = Path(root)
    submissions = read_submissions(root / SUBMISSIONS)
    try:
        recorded = json.loads((root / DOCUMENT).read_bytes())
    except (OSError, ValueError) as error:
        problem = f"{root / DOCUMENT}: cannot be read ({error}): run `bbbench leaderboard build`"
        return Checked([problem], len(submissions), 0, 0, time.perf_counter() - began)
    problems = _stale_inputs(root, recorded, submissions, board)
    episodes = 0
    if not problems:
        built = generate(
            root,
            board,
            cache=False,
            workers=workers,
            backend=backend,
            address=address,
            on_episodes=on_episodes,
        )
        problems = differences(root, built.files)
        episodes = built.episodes
    return Checked(
        problems, len(submissions), len(board.tasks), episodes, time.perf_counter() - began
    )


def _stale_inputs(
    root: Path, recorded: dict[str, Any], submissions: list[Submission], board: Board
) -> list[str]:
    problems = []
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
    entries = {
        entry["slug"]: entry for track in recorded.get("tracks", []) for entry in track["entries"]
    }
    for submission in submissions:
        entry = entries.get(submission.slug)
        where = f"{root / SUBMISSIONS / submission.slug}"
        if entry is None:
            problems.append(
                f"{where}: a submission that is not on the board: run `bbbench leaderboard "
                f"build` and commit what it writes"
            )
            continue
        if submission.policy_file is not None:
            sha = hashlib.sha256(submission.policy_file.read_bytes()).hexdigest()
            if sha != entry["policy"]["sha256"]:
                problems.append(
                    f"{submission.policy_file}: SHA-256 {sha[:16]}..., the board was built "
                    f"from {str(entry['policy']['sha256'])[:16]}...: the policy file changed"
                )
        if entry["submission"] != submission.metadata:
            changed = sorted(
                key
                for key in {*entry["submission"], *submission.metadata}
                if entry["submission"].get(key) != submission.metadata.get(key)
            )
            problems.append(
                f"{where}/{SUBMISSION_FILE}: changed since the board was built "
                f"(field {', '.join(repr(key) for key in changed)})"
            )
    slugs = {submission.slug for submission in submissions}
    problems += [
        f"entry {slug!r}: on the board, but {root / SUBMISSIONS / slug} is gone"
        for slug in entries
        if slug not in slugs
    ]
    return problems

"""Leaderboards: submissions in the repository, scored by the shipped harness, ranked with
intervals, and checked by CI (`bbbench leaderboard build | check | add | show`).

A leaderboard folder (`leaderboards/` in the repository) holds:

    submissions/<slug>/submission.json   metadata (docs/submission-schema.json)
    submissions/<slug>/policy.zip        the policy, unless it names a built-in
    results/<slug>.json                  its `bbbench eval --json` document
    bbbench-v0.json                      the ranked board (docs/leaderboard-schema.json)
    README.md, index.html                the board as people read it

Everything but `submissions/` is generated, with the same bytes on every build
(no dates, fixed bootstrap seeds, deterministic SVG), so `check` can rebuild
from scratch and compare.

    from bbbench.leaderboard import build, check
    build("leaderboards")
    check("leaderboards").problems  # [] when every checked-in number is re-scored exactly
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bbbench.evaluation.results import dumps
from bbbench.files import write_all_atomic
from bbbench.leaderboard.board import (
    Board,
    BuildError,
    Scored,
    leaderboard_document,
    score,
)
from bbbench.leaderboard.submissions import (
    MAX_POLICY_BYTES,
    NORMALIZATION_FILE,
    POLICY_FILE,
    SUBMISSION_FILE,
    Submission,
    SubmissionError,
    check_policy,
    check_policy_size,
    check_slug,
    read_submission,
    read_submissions,
    validate,
)
from bbbench.leaderboard.views import markdown, page, with_baselines

__all__ = [
    "DOCUMENT",
    "MAX_POLICY_BYTES",
    "Board",
    "BuildError",
    "Built",
    "Checked",
    "SubmissionError",
    "add",
    "build",
    "check",
    "generate",
]

DOCUMENT = "bbbench-v0.json"
RESULTS = "results"
SUBMISSIONS = "submissions"
DEFAULT_BOARD = Board()  # what the `bbbench leaderboard` command plays


@dataclasses.dataclass(frozen=True)
class Built:
    """A generated leaderboard: its files (path inside the folder -> bytes) and what it
    took to make them."""

    files: dict[str, bytes]
    document: dict[str, Any]
    played: int  # episodes played (the rest came from stored results)
    episodes: int  # episodes on the board


def generate(
    root: str | Path,
    board: Board = DEFAULT_BOARD,
    cache: bool = True,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
    on_episodes: Callable[[int], None] | None = None,
    extra: Submission | None = None,
) -> Built:
    """Score the submissions in `root` (and `extra`, one not yet written there) and
    generate every file of the board, in memory. With `cache`, a task result stored
    in `root/results` is reused when its key matches."""
    root = Path(root)
    submissions = read_submissions(root / SUBMISSIONS)
    if extra is not None:
        submissions = sorted([*submissions, extra], key=lambda s: s.slug)
    scored = score(
        submissions,
        board,
        stored=root / RESULTS if cache else None,
        workers=workers,
        backend=backend,
        address=address,
        on_episodes=on_episodes,
    )
    built = _files(scored, board)
    readme = root.parent / "README.md"  # the project's, where the board sits in a repository
    if readme.is_file():
        text = with_baselines(readme.read_text(encoding="utf-8"), built.document)
        if text is not None:
            built.files["../README.md"] = text.encode()
    return built


def _files(scored: list[Scored], board: Board) -> Built:
    document = leaderboard_document(scored, board)
    results = {entry.submission.slug: entry.results for entry in scored}
    files = {
        DOCUMENT: dumps(document).encode(),
        "README.md": markdown(document).encode(),
        "index.html": page(document, results).encode(),
        **{f"{RESULTS}/{slug}.json": dumps(doc).encode() for slug, doc in results.items()},
    }
    episodes = sum(
        block["aggregate"]["episodes"] for doc in results.values() for block in doc["tasks"]
    )
    return Built(files, document, sum(entry.played for entry in scored), episodes)


def build(root: str | Path, board: Board = DEFAULT_BOARD, **options: Any) -> Built:
    """`generate`, then write the files into `root`: each atomically, and all of them
    only once every episode is scored (an interrupted build changes nothing).
    Results of submissions that are gone are removed."""
    built = generate(root, board, **options)
    write(Path(root), built.files)
    return built


def write(root: Path, files: dict[str, bytes]) -> None:
    """Replace the generated files of the board in `root` by `files`, all at once; remove
    the results of submissions that are gone."""
    (root / RESULTS).mkdir(parents=True, exist_ok=True)
    stale = [
        path
        for path in sorted((root / RESULTS).glob("*.json"))
        if f"{RESULTS}/{path.name}" not in files
    ]
    write_all_atomic({root / name: data for name, data in files.items()})
    for path in stale:
        path.unlink()


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
        problems = _differences(root, built.files)
        episodes = built.episodes
    return Checked(
        problems, len(submissions), len(board.tasks), episodes, time.perf_counter() - began
    )


def _stale_inputs(
    root: Path, recorded: dict[str, Any], submissions: list[Submission], board: Board
) -> list[str]:
    from bbbench.tasks.suite import spec

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


def _differences(root: Path, files: dict[str, bytes], limit: int = 12) -> list[str]:
    """Each generated file against the one checked in: where they differ, readably."""
    problems = []
    for name, rebuilt in files.items():
        path = root / name
        if not path.is_file():
            problems.append(f"{path}: missing (the rebuild writes it)")
            continue
        recorded = path.read_bytes()
        if recorded == rebuilt:
            continue
        if name.endswith(".json"):
            try:
                found = _json_differences(json.loads(recorded), json.loads(rebuilt), name)
            except ValueError:
                found = [f"{name}: not valid JSON"]
            problems += found or [f"{path}: same data, other bytes (formatting)"]
        else:
            problems.append(_first_line_difference(path, recorded, rebuilt))
    problems += [
        f"{path}: no submission {path.stem!r} any more (the rebuild removes it)"
        for path in sorted((root / RESULTS).glob("*.json"))
        if f"{RESULTS}/{path.name}" not in files
    ]
    if len(problems) > limit:
        problems = [*problems[:limit], f"... and {len(problems) - limit} more differences"]
    return problems


def _label(item: Any, index: int) -> str:
    if isinstance(item, dict):
        for key in ("slug", "task", "track", "seed"):
            if key in item:
                return str(item[key])
    return str(index)


def _json_differences(old: Any, new: Any, path: str) -> list[str]:
    if isinstance(old, dict) and isinstance(new, dict):
        found = []
        for key in [*old, *(k for k in new if k not in old)]:
            if key not in new:
                found.append(f"{path}.{key}: checked in, not in the rebuild")
            elif key not in old:
                found.append(f"{path}.{key}: in the rebuild, not checked in")
            else:
                found += _json_differences(old[key], new[key], f"{path}.{key}")
        return found
    if isinstance(old, list) and isinstance(new, list):
        old_labels = [_label(item, i) for i, item in enumerate(old)]
        new_labels = [_label(item, i) for i, item in enumerate(new)]
        if old_labels != new_labels:
            return [
                f"{path}: checked in [{', '.join(old_labels)}], rebuilt [{', '.join(new_labels)}]"
            ]
        found = []
        for label, a, b in zip(old_labels, old, new, strict=True):
            found += _json_differences(a, b, f"{path}[{label}]")
        return found
    if old != new or type(old) is not type(new):
        return [f"{path}: checked in {json.dumps(old)[:60]}, rebuilt {json.dumps(new)[:60]}"]
    return []


def _first_line_difference(path: Path, recorded: bytes, rebuilt: bytes) -> str:
    old, new = recorded.decode(errors="replace").splitlines(), rebuilt.decode().splitlines()
    for number, (a, b) in enumerate(zip(old, new, strict=False), start=1):
        if a != b:
            return f"{path}: differs from the rebuild from line {number}: {a[:70]!r} vs {b[:70]!r}"
    return f"{path}: {len(old)} lines checked in, {len(new)} rebuilt"


def add(
    root: str | Path,
    policy: str,
    slug: str,
    metadata: dict[str, Any],
    vecnormalize: str | Path | None = None,
    board: Board = DEFAULT_BOARD,
    **options: Any,
) -> Built:
    """Add a submission: check it (slug, fields, the policy read safely, its action mode),
    score it (stored results of the others are reused), then write its folder
    `root/submissions/<slug>/` and the regenerated board. Nothing is written if any
    of it fails. `policy`: a policy file, or a built-in policy's name."""
    from bbbench.policies import BUILTIN_POLICIES, PolicyError, load_policy

    root = Path(root)
    check_slug(slug)
    target = root / SUBMISSIONS / slug
    if target.exists():
        raise SubmissionError(f"{target}: the slug {slug!r} is taken; choose another --slug")
    metadata = dict(metadata)
    source = None
    if policy in BUILTIN_POLICIES:
        if vecnormalize is not None:
            raise SubmissionError(
                f"--vecnormalize is for a policy file, not the built-in {policy!r}"
            )
        metadata["builtin"] = policy
        metadata.setdefault("action_mode", BUILTIN_POLICIES[policy]().action_mode)
    else:
        source = Path(policy)
        if not source.is_file():
            raise SubmissionError(
                f"{policy}: no such file, and not a built-in policy "
                f"({', '.join(sorted(BUILTIN_POLICIES))})"
            )
        check_policy_size(source)
        try:  # refused here, the file never enters submissions/
            loaded = load_policy(source, vecnormalize=vecnormalize)
        except PolicyError as error:
            raise SubmissionError(f"{policy}: {error}") from None
        check_policy(loaded, metadata.setdefault("action_mode", loaded.action_mode), policy)
    validate(metadata, "the submission (from the command's options)")
    (root / SUBMISSIONS).mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{slug}.", suffix=".partial", dir=root / SUBMISSIONS))
    try:
        folder = staging / slug
        folder.mkdir()
        text = json.dumps(metadata, indent=2, ensure_ascii=False) + "\n"
        (folder / SUBMISSION_FILE).write_text(text, encoding="utf-8")
        if source is not None:
            shutil.copyfile(source, folder / POLICY_FILE)
            if vecnormalize is not None:
                shutil.copyfile(vecnormalize, folder / NORMALIZATION_FILE)
        submission = read_submission(folder)
        built = generate(root, board, extra=submission, **options)
        os.rename(folder, target)  # the submission, whole, then its board
        write(root, built.files)
        return built
    finally:
        shutil.rmtree(staging, ignore_errors=True)

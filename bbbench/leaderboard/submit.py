"""`bbbench leaderboard add`: check a submission, score it, and write it with its board."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

from bbbench.leaderboard.board import Board
from bbbench.leaderboard.generation import DEFAULT_BOARD, SUBMISSIONS, Built, generate, write
from bbbench.leaderboard.submissions import (
    NORMALIZATION_FILE,
    ONNX_FILE,
    POLICY_FILE,
    SUBMISSION_FILE,
    SubmissionError,
    builtin_identity,
    check_policy,
    check_policy_size,
    check_slug,
    policy_identity,
    read_submission,
    read_submissions,
    validate,
)
from bbbench.policies import BUILTIN_POLICIES, PolicyError, load_policy
from bbbench.policies.errors import NoContract
from bbbench.policies.onnx.policy import OnnxPolicy


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
        except NoContract as error:
            raise SubmissionError(error.for_file_only()) from None
        except PolicyError as error:  # its message names the file (once)
            named = policy in str(error) or source.name in str(error)
            raise SubmissionError(str(error) if named else f"{policy}: {error}") from None
        check_policy(loaded, metadata.setdefault("action_mode", loaded.action_mode), policy)
    validate(metadata, "the submission (from the command's options)")
    _check_new(root, policy, source, vecnormalize, metadata)
    (root / SUBMISSIONS).mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{slug}.", suffix=".partial", dir=root / SUBMISSIONS))
    try:
        folder = staging / slug
        folder.mkdir()
        text = json.dumps(metadata, indent=2, ensure_ascii=False) + "\n"
        (folder / SUBMISSION_FILE).write_text(text, encoding="utf-8")
        if source is not None:
            name = ONNX_FILE if isinstance(loaded, OnnxPolicy) else POLICY_FILE
            shutil.copyfile(source, folder / name)
            if vecnormalize is not None:
                shutil.copyfile(vecnormalize, folder / NORMALIZATION_FILE)
        try:
            submission = read_submission(folder)
            built = generate(root, board, extra=submission, **options)
        except SubmissionError as error:  # named where it was to go, not where it was staged
            raise SubmissionError(str(error).replace(str(folder), str(target))) from None
        os.rename(folder, target)  # the submission, whole, then its board
        write(root, built.files)
        return built
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _check_new(
    root: Path,
    policy: str,
    source: Path | None,
    vecnormalize: str | Path | None,
    metadata: dict[str, Any],
) -> None:
    """`SubmissionError` if the policy is on the board already, under another slug."""
    if source is None:
        identity = builtin_identity(policy, metadata["action_mode"])
        what = f"the built-in {policy!r} ({metadata['action_mode']}) is on the board already"
    else:
        identity = policy_identity(source, None if vecnormalize is None else Path(vecnormalize))
        what = f"{policy}: the same policy bytes are on the board already"
    for entry in read_submissions(root / SUBMISSIONS):
        if entry.identity() == identity:
            raise SubmissionError(f"{what}, as {entry.slug!r}: one policy is one entry")

"""`bbbench leaderboard add`: check a run, score it, and write it with its board.

A run enters a method: a new method (its folder is written whole) or one on the board
already, whose recipe the run must share. A run with a training seed goes to
`runs/s<seed>/`; a run without one (a controller) is a method of one run.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

from bbbench.leaderboard.board import Board
from bbbench.leaderboard.fields import INLINE_RUN, METHOD_FIELDS, RUN_FIELDS, validate
from bbbench.leaderboard.generation import DEFAULT_BOARD, SUBMISSIONS, Built, generate, write
from bbbench.leaderboard.submissions import (
    NORMALIZATION_FILE,
    ONNX_FILE,
    POLICY_FILE,
    RUN_FILE,
    RUNS,
    SUBMISSION_FILE,
    SubmissionError,
    builtin_identity,
    check_policy,
    check_policy_size,
    check_slug,
    policy_identity,
    read_method,
    read_methods,
)
from bbbench.policies import BUILTIN_POLICIES, PolicyError, load_policy
from bbbench.policies.errors import NoContract
from bbbench.policies.onnx.policy import OnnxPolicy


def add(
    root: str | Path,
    policy: str,
    slug: str,
    method: dict[str, Any],
    run: dict[str, Any],
    vecnormalize: str | Path | None = None,
    board: Board = DEFAULT_BOARD,
    **options: Any,
) -> Built:
    """Add a run of the method `slug`: check it (slug, fields, the policy read safely, its
    action mode, its recipe against the method's), score it (stored results of the others
    are reused), then write it and the regenerated board. Nothing is written if any of it
    fails. `policy`: a policy file, or a built-in policy's name; `method`: the method's
    fields (for a method on the board already: any given must be its own); `run`: the
    run's fields (`RUN_FIELDS`)."""
    root = Path(root)
    check_slug(slug)
    validate(run, RUN_FIELDS, "the run (from the command's options)")
    folder = root / SUBMISSIONS / slug
    existing = read_method(folder) if folder.exists() else None
    seed = run["training_seed"]
    if existing is not None and not (folder / RUNS).exists():
        raise SubmissionError(
            f"{folder}: the method {slug!r} is one run in its own folder, with no room for "
            f"another; choose another slug"
        )
    if existing is not None and seed is None:
        raise SubmissionError(
            f"{folder}: the method {slug!r} is on the board; a run more of it needs its "
            f"training seed"
        )
    method = _method_fields(existing, method, run, folder)
    name = _checked_policy(policy, vecnormalize, method)
    source = None if name is None else Path(policy)
    if source is None:
        method["builtin"] = policy
    if source is None and seed is not None:
        raise SubmissionError(f"the built-in {policy!r} is a controller: give no training seed")
    validate(
        method if seed is None else _without_run(method),
        METHOD_FIELDS,
        "the method (from the command's options)",
    )
    _check_new(root, policy, source, vecnormalize, method)
    (root / SUBMISSIONS).mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{slug}.", suffix=".partial", dir=root / SUBMISSIONS))
    try:
        staged = staging / slug
        if existing is not None:
            shutil.copytree(folder, staged)
        else:
            staged.mkdir()
            _write_json(staged / SUBMISSION_FILE, method if seed is None else _without_run(method))
        target = staged if seed is None else staged / RUNS / f"s{seed}"
        if seed is not None:
            if target.exists():
                raise SubmissionError(
                    f"{folder / RUNS / target.name}: training seed {seed} is on the board "
                    f"already; each run of a method has its own training seed"
                )
            target.mkdir(parents=True)
            _write_json(target / RUN_FILE, run)
        if source is not None:
            shutil.copyfile(source, target / name)
            if vecnormalize is not None:
                shutil.copyfile(vecnormalize, target / NORMALIZATION_FILE)
        try:
            staged_method = read_method(staged)
            built = generate(root, board, extra=staged_method, **options)
        except SubmissionError as error:  # named where it was to go, not where it was staged
            raise SubmissionError(str(error).replace(str(staged), str(folder))) from None
        _place(staged, folder, seed)  # the method or its new run, then its board
        write(root, built.files)
        return built
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _method_fields(
    existing: Any, given: dict[str, Any], run: dict[str, Any], folder: Path
) -> dict[str, Any]:
    """The method's fields: the given ones for a new method (with the run's records, for
    a method of one run), else the method's own, any given one checked against them."""
    if existing is None:
        return {**given, "recipe": run["recipe"], **{k: run[k] for k in INLINE_RUN}}
    recipe = existing.metadata["recipe"]
    if run["recipe"] != recipe:
        key = next(key for key in recipe if run["recipe"].get(key) != recipe[key])
        raise SubmissionError(
            f"{folder / SUBMISSION_FILE}: the run's recipe's {key!r} is "
            f"{json.dumps(run['recipe'].get(key))}, the method's {json.dumps(recipe[key])}; "
            f"runs of one method share its recipe: give this run a method of its own"
        )
    for key, value in given.items():
        if value is not None and existing.metadata.get(key) != value:
            raise SubmissionError(
                f"{folder / SUBMISSION_FILE}: the method's {key!r} is "
                f"{json.dumps(existing.metadata.get(key))}, the run's {json.dumps(value)}; "
                f"a run of another recipe is another method: choose another slug"
            )
    return dict(existing.metadata)


def _without_run(method: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in method.items() if k not in INLINE_RUN}


def _checked_policy(
    policy: str, vecnormalize: str | Path | None, method: dict[str, Any]
) -> str | None:
    """Read the policy file safely and check it: the name it takes in the run's folder
    (None for a built-in's name)."""
    if policy in BUILTIN_POLICIES:
        if vecnormalize is not None:
            raise SubmissionError(
                f"--vecnormalize is for a policy file, not the built-in {policy!r}"
            )
        method.setdefault("action_mode", BUILTIN_POLICIES[policy]().action_mode)
        return None
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
    check_policy(loaded, method.setdefault("action_mode", loaded.action_mode), policy)
    return ONNX_FILE if isinstance(loaded, OnnxPolicy) else POLICY_FILE


def _write_json(path: Path, data: dict[str, Any]) -> None:
    path.write_text(json.dumps(data, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")


def _place(staged: Path, folder: Path, seed: int | None) -> None:
    """Put the staged method where it goes, in one rename: a new method's whole folder, or
    the new run's folder into its method (whose other files the run leaves as they were)."""
    if not folder.exists():
        os.rename(staged, folder)
    else:
        os.rename(staged / RUNS / f"s{seed}", folder / RUNS / f"s{seed}")


def _check_new(
    root: Path,
    policy: str,
    source: Path | None,
    vecnormalize: str | Path | None,
    method: dict[str, Any],
) -> None:
    """`SubmissionError` if the policy is on the board already, in any method."""
    if source is None:
        identity = builtin_identity(policy, method["action_mode"])
        what = f"the built-in {policy!r} ({method['action_mode']}) is on the board already"
    else:
        identity = policy_identity(source, None if vecnormalize is None else Path(vecnormalize))
        what = f"{policy}: the same policy bytes are on the board already"
    for entry in read_methods(root / SUBMISSIONS):
        for run in entry.runs:
            if run.identity() == identity:
                raise SubmissionError(f"{what}, as {run.slug!r}: one policy is one run")

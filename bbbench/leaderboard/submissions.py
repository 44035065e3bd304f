"""Submissions: one folder per method, its runs beneath it.

    submissions/<method>/submission.json          the method (`METHOD_FIELDS`)
    submissions/<method>/runs/<run>/run.json      a run's records (`RUN_FIELDS`)
    submissions/<method>/runs/<run>/policy.onnx   its policy (or policy.zip)

A method is its recipe and its runs, one policy per training seed
(docs/submission-schema.json, docs/run-schema.json). A method of one run may keep
it in its own folder: its policy file (or a built-in's name) and the run's
records in submission.json; a deterministic controller is such a method. A run's
slug, which names its results (`results/<slug>.json`), is `<method>-<run>`, or the
method's for a method of one run in its own folder.

A submission is data a stranger wrote. Each file is read as JSON with a size cap and
checked field by field; a policy file is capped at `MAX_POLICY_BYTES` and read with
the same safe loader as `bbbench eval` (nothing from it is unpickled or run). Every
problem is a `SubmissionError` whose message names the file and the field.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import re
from pathlib import Path
from typing import Any

from bbbench.leaderboard.fields import (
    INLINE_RUN,
    METHOD_FIELDS,
    RUN_FIELDS,
    SubmissionError,
    validate,
)
from bbbench.policies import Policy, PolicyError, fitting_tasks, load_policy

SUBMISSION_FILE = "submission.json"  # the method
RUN_FILE = "run.json"  # a run's records
RUNS = "runs"  # the method's runs, one folder each
POLICY_FILE = "policy.zip"  # a stable-baselines3 zip
ONNX_FILE = "policy.onnx"  # an ONNX model, its contract in its metadata (bbbench export)
POLICY_FILES = (POLICY_FILE, ONNX_FILE)
NORMALIZATION_FILE = "vecnormalize.pkl"  # VecNormalize statistics, for a zip trained inside it
MAX_POLICY_BYTES = 5 * 1024 * 1024
MAX_SUBMISSION_BYTES = 64 * 1024
# A folder name that is safe everywhere: lower-case letters, digits, inner hyphens.
SLUG = re.compile(r"[a-z0-9](?:[a-z0-9-]{0,46}[a-z0-9])?")
SLUG_RULE = "2-48 lower-case letters, digits and inner hyphens, like 'ppo-lstm-2'"
RUN_NAME = re.compile(r"[a-z0-9]{1,12}")  # a run's folder: 's0', 's1', ...
RUN_RULE = "1-12 lower-case letters and digits, like 's0'"


@dataclasses.dataclass(frozen=True)
class Run:
    """One policy of a method: where it is, its records, and its method's metadata."""

    slug: str  # its results' name: <method>-<run>, or the method's own
    folder: Path  # the folder that holds its policy file
    record: dict[str, Any]  # its run fields
    method: dict[str, Any]  # its method's metadata (action mode, built-in)
    files: tuple[Path, ...]  # the submission files its numbers depend on

    @property
    def policy_file(self) -> Path | None:
        if "builtin" in self.method:
            return None
        return next((p for p in self.policy_paths() if p.exists()), self.folder / POLICY_FILE)

    def policy_paths(self) -> list[Path]:
        return [self.folder / name for name in POLICY_FILES]

    @property
    def normalization_file(self) -> Path | None:
        path = self.folder / NORMALIZATION_FILE
        return path if self.policy_file and path.is_file() else None

    def load_policy(self) -> Policy:
        """The policy, read safely and checked against the method's action mode;
        `SubmissionError` naming the file for a refused one."""
        declared = self.method["action_mode"]
        if self.policy_file is None:
            try:
                policy = load_policy(self.method["builtin"], action_mode=declared)
            except PolicyError as error:
                raise SubmissionError(f"{self.folder / SUBMISSION_FILE}: {error}") from None
        else:
            where = self.policy_file
            check_policy_size(where)
            try:
                policy = load_policy(where, vecnormalize=self.normalization_file)
            except PolicyError as error:
                raise SubmissionError(f"{where}: {error}") from None
        return check_policy(policy, declared, self.policy_file or self.folder / SUBMISSION_FILE)

    def identity(self) -> tuple[str, ...]:
        """What plays: a built-in in its action mode, or the policy file's bytes (and its
        normalizer's). Two runs with one identity are one policy twice."""
        if self.policy_file is None:
            return builtin_identity(self.method["builtin"], self.method["action_mode"])
        return policy_identity(self.policy_file, self.normalization_file)

    def describe_identity(self) -> str:
        if self.policy_file is None:
            return f"the built-in {self.method['builtin']!r} ({self.method['action_mode']})"
        return f"the same policy bytes ({self.policy_file.name})"


@dataclasses.dataclass(frozen=True)
class Method:
    """A method: its folder, its checked metadata and its runs, in training-seed order."""

    slug: str
    folder: Path
    metadata: dict[str, Any]
    runs: tuple[Run, ...]

    @property
    def learned(self) -> bool:
        """Trained (its recipe spends steps), not a controller set by hand."""
        return self.metadata["recipe"]["world_steps"] > 0


def builtin_identity(name: str, action_mode: str) -> tuple[str, ...]:
    """A built-in's identity: its name in its action mode."""
    return ("builtin", name, action_mode)


def policy_identity(policy: Path, normalization: Path | None) -> tuple[str, ...]:
    """A policy file's identity: its SHA-256, and its normalizer's if it has one."""
    hashes = [hashlib.sha256(p.read_bytes()).hexdigest() for p in (policy, normalization) if p]
    return ("file", *hashes)


def check_distinct(runs: list[Run]) -> None:
    """`SubmissionError` for one policy twice (the same bytes, or one built-in in one
    action mode), and for two runs under one results name: a board ranks policies, not
    copies."""
    seen: dict[tuple[str, ...], Run] = {}
    slugs: dict[str, Run] = {}
    for run in runs:
        first = slugs.setdefault(run.slug, run)
        if first is not run:
            raise SubmissionError(
                f"{run.folder}: its results would be named {run.slug!r}, as {first.folder}'s "
                f"are: rename one of the folders"
            )
        first = seen.setdefault(run.identity(), run)
        if first is not run:
            raise SubmissionError(
                f"{run.folder}: {run.describe_identity()} as {first.slug!r} already; one "
                f"policy is one run of one method: remove one of them"
            )


def check_policy(policy: Policy, declared_mode: str, where: Path | str) -> Policy:
    """`policy`, if it acts in the declared action mode and fits a task of the suite."""
    if policy.action_mode != declared_mode:
        raise SubmissionError(
            f"{where}: field 'action_mode' is {declared_mode!r}, but the policy acts in "
            f"{policy.action_mode} mode ({policy.spaces_text()})"
        )
    if not fitting_tasks(policy):
        raise SubmissionError(
            f"{where}: the policy ({policy.spaces_text()}) fits no task of the suite"
        )
    return policy


def check_policy_size(path: Path) -> None:
    size = path.stat().st_size
    if size > MAX_POLICY_BYTES:
        raise SubmissionError(
            f"{path}: {size / 2**20:.1f} MB, over the {MAX_POLICY_BYTES // 2**20} MB cap for a "
            f"policy file (an MLP policy for this suite is well under 1 MB)"
        )


def check_slug(slug: str) -> str:
    if not isinstance(slug, str) or not SLUG.fullmatch(slug):
        raise SubmissionError(f"slug {slug!r} is not a safe folder name: use {SLUG_RULE}")
    return slug


def _read_json(path: Path, what: str) -> Any:
    if not path.is_file():
        raise SubmissionError(f"{path}: missing; {what}")
    if path.stat().st_size > MAX_SUBMISSION_BYTES:
        raise SubmissionError(f"{path}: over {MAX_SUBMISSION_BYTES // 1024} kB")
    try:
        return json.loads(path.read_bytes(), object_pairs_hook=_no_duplicate_keys)
    except UnicodeDecodeError:
        raise SubmissionError(f"{path}: not UTF-8 text") from None
    except ValueError as error:  # json.JSONDecodeError is a ValueError
        raise SubmissionError(f"{path}: not valid JSON ({error})") from None


def _no_duplicate_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    keys = [key for key, _ in pairs]
    for key in keys:
        if keys.count(key) > 1:
            raise ValueError(f"the field {key!r} is given twice")
    return dict(pairs)


def _check_files(folder: Path, allowed: set[str], holds: str) -> None:
    for item in sorted(folder.iterdir()):
        if item.name not in allowed or item.is_symlink():
            raise SubmissionError(f"{item}: not part of a submission; {holds}")
        if item.name != RUNS and not item.is_file():
            raise SubmissionError(f"{item}: not a regular file; {holds}")


def _policy_files(folder: Path, where: Path, builtin: bool) -> None:
    """Check the policy files of a run's folder: one policy file, or a built-in's name."""
    files = [folder / name for name in POLICY_FILES if (folder / name).exists()]
    if len(files) > 1:
        raise SubmissionError(f"{folder}: holds both {POLICY_FILE} and {ONNX_FILE}: keep one")
    if builtin and files:
        raise SubmissionError(
            f"{where}: field 'builtin' names a built-in policy, and the folder also holds "
            f"{files[0].name}: keep one"
        )
    if not builtin and not files:
        raise SubmissionError(
            f"{folder}: no {POLICY_FILE} or {ONNX_FILE}; add the run's policy file"
            + ("" if folder.parent.name == RUNS else ", or name a built-in with 'builtin'")
        )
    if files:
        check_policy_size(files[0])
    statistics = folder / NORMALIZATION_FILE
    if statistics.exists() and (builtin or files[0].name == ONNX_FILE):
        raise SubmissionError(
            f"{statistics}: only a zip takes statistics (a built-in none; an ONNX graph "
            f"normalizes inside)"
        )


def read_method(folder: Path) -> Method:
    """The method in `folder` (named by its slug), checked: folder names, files, fields,
    and that its runs share its recipe and differ in training seed."""
    slug = folder.name
    try:
        check_slug(slug)
    except SubmissionError as error:
        raise SubmissionError(f"{folder}: {error}") from None
    holds = (
        f"a method's folder holds {SUBMISSION_FILE} and either {RUNS}/ (a folder per run) or "
        f"its one run's {POLICY_FILE} or {ONNX_FILE} (unless it names a built-in), and "
        f"optionally {NORMALIZATION_FILE} beside a zip"
    )
    _check_files(folder, {SUBMISSION_FILE, RUNS, *POLICY_FILES, NORMALIZATION_FILE}, holds)
    path = folder / SUBMISSION_FILE
    metadata = validate(
        _read_json(path, "every method's folder needs one"), METHOD_FIELDS, str(path)
    )
    inline = [name for name in INLINE_RUN if name in metadata]
    runs_folder = folder / RUNS
    if runs_folder.exists():
        if (
            inline
            or "builtin" in metadata
            or any((folder / name).exists() for name in (*POLICY_FILES, NORMALIZATION_FILE))
        ):
            raise SubmissionError(
                f"{folder}: has {RUNS}/ and a run of its own ({', '.join(inline) or 'a policy'}"
                f"); keep each run's policy and records in {RUNS}/<run>/"
            )
        runs = _read_runs(runs_folder, slug, metadata)
    else:
        missing = [name for name in INLINE_RUN if name not in metadata]
        if missing:
            raise SubmissionError(
                f"{path}: missing field {missing[0]!r} (a method without {RUNS}/ is one run, "
                f"and its records are in this file)"
            )
        _policy_files(folder, path, "builtin" in metadata)
        run = {name: metadata[name] for name in INLINE_RUN}
        runs = (Run(slug, folder, run, metadata, _files(folder, path)),)
    _check_one_recipe(metadata, runs)
    return Method(slug, folder, metadata, runs)


def _read_runs(folder: Path, method: str, metadata: dict[str, Any]) -> tuple[Run, ...]:
    runs = []
    for item in sorted(folder.iterdir()):
        if item.is_symlink() or not item.is_dir() or not RUN_NAME.fullmatch(item.name):
            raise SubmissionError(f"{item}: not a run's folder ({RUNS}/<run>/, <run>: {RUN_RULE})")
        _check_files(
            item,
            {RUN_FILE, *POLICY_FILES, NORMALIZATION_FILE},
            f"a run's folder holds {RUN_FILE} and its {POLICY_FILE} or {ONNX_FILE} "
            f"(and optionally {NORMALIZATION_FILE} beside a zip)",
        )
        path = item / RUN_FILE
        record = validate(_read_json(path, "every run needs its records"), RUN_FIELDS, str(path))
        _policy_files(item, path, builtin=False)
        runs.append(Run(f"{method}-{item.name}", item, record, metadata, _files(item, path)))
    if not runs:
        raise SubmissionError(f"{folder}: no runs; add a folder per run, or remove {RUNS}/")
    by_seed: dict[Any, Run] = {}
    for run in runs:
        first = by_seed.setdefault(run.record["training_seed"], run)
        if first is not run:
            raise SubmissionError(
                f"{run.folder / RUN_FILE}: training seed {run.record['training_seed']} is "
                f"{first.folder.name}'s too; each run of a method has its own training seed"
            )
    return tuple(sorted(runs, key=lambda run: (run.record["training_seed"] or 0, run.slug)))


def _files(folder: Path, record: Path) -> tuple[Path, ...]:
    method = folder if record.name == SUBMISSION_FILE else folder.parent.parent
    return tuple(dict.fromkeys([method / SUBMISSION_FILE, record]))


def _check_one_recipe(metadata: dict[str, Any], runs: tuple[Run, ...]) -> None:
    """`SubmissionError` for a run whose recorded recipe is not its method's, or a method
    of several runs with one that was not trained."""
    recipe = metadata["recipe"]
    for run in runs:
        recorded = run.record.get("recipe", recipe)
        if recorded != recipe:
            field = next(key for key in recipe if recorded.get(key) != recipe.get(key))
            raise SubmissionError(
                f"{run.folder / RUN_FILE}: its recipe's {field!r} is "
                f"{json.dumps(recorded[field])}, the method's {json.dumps(recipe[field])}; runs "
                f"of one method share its recipe: give this run a method of its own"
            )
        if len(runs) > 1 and run.record["training_seed"] is None:
            raise SubmissionError(
                f"{run.folder / RUN_FILE}: field 'training_seed' is null, but a method of "
                f"several runs is one per training seed"
            )


def read_methods(folder: Path) -> list[Method]:
    """Every method under `folder` (`<root>/submissions`), in slug order; no policy twice."""
    if not folder.is_dir():
        return []
    entries = [item for item in sorted(folder.iterdir()) if not item.name.startswith(".")]
    for item in entries:
        if not item.is_dir() or item.is_symlink():
            raise SubmissionError(f"{item}: not a method's folder (submissions/<method>/)")
    methods = [read_method(item) for item in entries]
    check_distinct([run for method in methods for run in method.runs])
    return methods

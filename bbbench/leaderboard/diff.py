"""Where a rebuilt board differs from the one checked in, said readably."""

from __future__ import annotations

import json
from collections.abc import Collection
from pathlib import Path
from typing import Any

from bbbench.evaluation.results import dumps, loads
from bbbench.leaderboard.generation import RESULTS, stale
from bbbench.leaderboard.page import is_figure


def differences(
    root: Path, files: dict[str, bytes], skip: Collection[str] = (), limit: int = 12
) -> list[str]:
    """Each generated file against the one checked in (but those in `skip`): where they
    differ, readably; the numbers that differ, in one line (how many, in how many files,
    by how much at most: a machine that does not reproduce the board moves many in the
    last bits); the figures that differ, in one line after the rest (they draw what the
    data says). A JSON document's `platform` block, which names the build it was made on,
    is not compared."""
    problems, figures, numbers = [], [], {}
    for name, rebuilt in files.items():
        if name in skip:
            continue
        path = root / name
        if is_figure(name):
            if not path.is_file() or path.read_bytes() != rebuilt:
                figures.append(name)
            continue
        if not path.is_file():
            problems.append(f"{path}: missing (the rebuild writes it)")
            continue
        recorded = path.read_bytes()
        if recorded == rebuilt:
            continue
        if name.endswith(".json"):
            try:
                old, new = (_unplaced(loads(text)) for text in (recorded, rebuilt))
            except ValueError:
                problems.append(f"{name}: not valid JSON")
                continue
            if old == new and dumps(loads(recorded)).encode() != recorded:
                problems.append(f"{path}: same data, other bytes (formatting)")
            found = _json_differences(old, new, name)
            numbers.update({where: pair for where, pair in found if pair is not None})
            problems += [where for where, pair in found if pair is None]
        else:
            problems.append(_first_line_difference(path, recorded, rebuilt))
    if numbers:
        problems.append(numbers_differ(numbers))
    if figures:
        problems.append(
            f"{root}: figures missing or not as the rebuild draws them: {', '.join(figures)}"
        )
    for path in stale(root, files):
        gone = f"no run {path.stem!r}" if path.parent.name == RESULTS else "not drawn"
        problems.append(f"{path}: {gone} any more (the rebuild removes it)")
    if len(problems) > limit:
        problems = [*problems[:limit], f"... and {len(problems) - limit} more differences"]
    return problems


def numbers_differ(numbers: dict[str, tuple[float, float]], shown: int = 3) -> str:
    """One line for numbers that differ (where -> (checked in, rebuilt)): how many, in how
    many files, the largest difference, and the first few."""
    files = {where.split(".json", 1)[0] for where in numbers}
    gaps = {where: abs(new - old) for where, (old, new) in numbers.items()}
    first = "; ".join(
        f"{where}: checked in {old!r}, rebuilt {new!r}"
        for where, (old, new) in list(numbers.items())[:shown]
    )
    return (
        f"{len(numbers)} numbers in {len(files)} files differ from the checked-in board, by "
        f"at most {max(gaps.values()):.3g} (first: {first})"
    )


def _unplaced(document: Any) -> Any:
    """A JSON document without its `platform` block (where it was made)."""
    if isinstance(document, dict):
        return {key: value for key, value in document.items() if key != "platform"}
    return document


def _label(item: Any, index: int) -> str:
    if isinstance(item, dict):
        for key in ("slug", "task", "track", "seed"):
            if key in item:
                return str(item[key])
    return str(index)


def _json_differences(
    old: Any, new: Any, path: str
) -> list[tuple[str, tuple[float, float] | None]]:
    """Where two JSON documents differ: (where and what, None), or for two numbers that
    differ (where, (checked in, rebuilt))."""
    if isinstance(old, dict) and isinstance(new, dict):
        found = []
        for key in [*old, *(k for k in new if k not in old)]:
            if key not in new:
                found.append((f"{path}.{key}: checked in, not in the rebuild", None))
            elif key not in old:
                found.append((f"{path}.{key}: in the rebuild, not checked in", None))
            else:
                found += _json_differences(old[key], new[key], f"{path}.{key}")
        return found
    if isinstance(old, list) and isinstance(new, list):
        old_labels = [_label(item, i) for i, item in enumerate(old)]
        new_labels = [_label(item, i) for i, item in enumerate(new)]
        if old_labels != new_labels:
            listed = f"checked in [{', '.join(old_labels)}], rebuilt [{', '.join(new_labels)}]"
            return [(f"{path}: {listed}", None)]
        found = []
        for label, a, b in zip(old_labels, old, new, strict=True):
            found += _json_differences(a, b, f"{path}[{label}]")
        return found
    if _number(old) and _number(new) and old != new:
        return [(path, (old, new))]
    if old != new or type(old) is not type(new):
        return [
            (f"{path}: checked in {json.dumps(old)[:60]}, rebuilt {json.dumps(new)[:60]}", None)
        ]
    return []


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _first_line_difference(path: Path, recorded: bytes, rebuilt: bytes) -> str:
    old, new = recorded.decode(errors="replace").splitlines(), rebuilt.decode().splitlines()
    for number, (a, b) in enumerate(zip(old, new, strict=False), start=1):
        if a != b:
            return f"{path}: differs from the rebuild from line {number}: {a[:70]!r} vs {b[:70]!r}"
    return f"{path}: {len(old)} lines checked in, {len(new)} rebuilt"

"""Where a rebuilt board differs from the one checked in, said readably."""

from __future__ import annotations

import json
from collections.abc import Collection
from pathlib import Path
from typing import Any

from bbbench.leaderboard.generation import RESULTS, stale
from bbbench.leaderboard.page import is_figure


def differences(
    root: Path, files: dict[str, bytes], skip: Collection[str] = (), limit: int = 12
) -> list[str]:
    """Each generated file against the one checked in (but those in `skip`): where they
    differ, readably; the figures that differ, in one line after the rest (they draw
    what the data says)."""
    problems, figures = [], []
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
                found = _json_differences(json.loads(recorded), json.loads(rebuilt), name)
            except ValueError:
                found = [f"{name}: not valid JSON"]
            problems += found or [f"{path}: same data, other bytes (formatting)"]
        else:
            problems.append(_first_line_difference(path, recorded, rebuilt))
    if figures:
        problems.append(
            f"{root}: figures missing or not as the rebuild draws them: {', '.join(figures)}"
        )
    for path in stale(root, files):
        gone = f"no submission {path.stem!r}" if path.parent.name == RESULTS else "not drawn"
        problems.append(f"{path}: {gone} any more (the rebuild removes it)")
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

"""The tables of the choices' records (scripts/choices.py), as the docs print them:
docs/baselines.md's table of every choice, and docs/tasks.md's table of one task's
calibration, candidate by candidate.

    python scripts/choice_tables.py                                  # every choice
    python scripts/choice_tables.py --detail leggedbumps-difficulty  # one choice's candidates

scripts/check_docs.py runs each and compares its output with the block in the page.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

from choices import CHOICES, record_path


def table() -> str:
    """The Markdown table of the records: one row per choice."""
    lines = [
        "| choice | on | candidates: normalized (finished) | the rule's evidence | picked "
        "| shipped |",
        "|---|---|---|---|---|---|",
    ]
    for choice in CHOICES.values():
        path = record_path(choice.name)
        if not path.exists():
            lines.append(
                f"| {choice.question} | not made again yet | | {choice.rule} | | {choice.shipped} |"
            )
            continue
        record = json.loads(path.read_text())
        shown = "; ".join(
            f"{row['label']}: {row['score']:.3f} ("
            + ", ".join(f"{task['finished']:.0%}" for task in row["tasks"].values())
            + ")"
            for row in record["candidates"]
        )
        seeds = record["seeds"]
        where = f"{seeds['count']} validation seeds"
        verdict = "the same" if record["holds"] else f"**{record['picked']}**"
        if record["kind"] == "task":
            against = f"in the band: {', '.join(record['in_band']) or 'none'}"
        else:
            others = [row for row in record["candidates"] if "p_over_shipped" in row]
            best = max(others, key=lambda row: row["score"])
            point, (low, high) = best["p_over_shipped"]
            against = (
                f"best other, {best['label']}: P(it > shipped) {point:.3f} [{low:.3f}, {high:.3f}]"
            )
        lines.append(
            f"| {record['question']} | {where} | {shown} | {against} | {verdict} | "
            f"{record['shipped']} |"
        )
    return "\n".join(lines)


def detail(name: str) -> str:
    """One choice's candidates on its validation seeds: episodes finished, mean return and
    normalized score on each task, the value shipped in bold, and whether it holds."""
    choice = CHOICES[name]
    record = json.loads(record_path(name).read_text())
    tasks = [task_id.removeprefix("bbbench/") for task_id in record["tasks"]]
    header = " | ".join(f"{task}: finished, mean return, normalized" for task in tasks)
    lines = [f"| {choice.question} | {header} |", "|---|" + "---|" * len(tasks)]
    for row in record["candidates"]:
        label = row["label"]
        if label == record["shipped"]:
            label = f"**{label} (shipped)**"
        cells = [
            f"{round(task['finished'] * len(task['returns']))} / {len(task['returns'])}, "
            f"{task['mean_return']:.1f}, {task['normalized']:.3f}"
            for task in row["tasks"].values()
        ]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    seeds = record["seeds"]["count"]
    if record["holds"]:
        verdict = f"On the {seeds} validation seeds the value shipped holds"
    else:
        verdict = f"On the {seeds} validation seeds the rule picks **{record['picked']}**"
    return "\n".join([*lines, "", f"{verdict}. The rule: {record['rule']}."])


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--detail", metavar="NAME", choices=sorted(CHOICES))
    args = parser.parse_args(argv)
    print(detail(args.detail) if args.detail else table())
    return 0


if __name__ == "__main__":
    sys.exit(main())

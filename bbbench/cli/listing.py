"""`bbbench list`: the suite's tasks as a table."""

from __future__ import annotations

import argparse

import bbbench
from bbbench.tasks.suite import latest_version


def add_parser(commands) -> None:
    listing = commands.add_parser("list", help="print the suite's tasks as a table")
    listing.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    specs = [bbbench.spec(task_id) for task_id in bbbench.list_tasks()]
    rows = [
        ("task", "bots", "steps", "dt (s)", "max return", "eval seeds", "fingerprint", "summary")
    ]
    rows += [
        (
            spec.id,
            str(spec.group.n_bots) if spec.multi_agent else "1",
            str(spec.max_episode_steps),
            f"{spec.control_dt:g}",
            f"{spec.max_return:g}",
            f"{len(spec.eval_seeds)}",
            spec.fingerprint,
            spec.summary
            + (
                ""
                if latest_version(spec.id) == spec.id
                else f" (superseded by {latest_version(spec.id)})"
            ),
        )
        for spec in specs
    ]
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    for row in rows:
        print(
            "  ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True)).rstrip()
        )

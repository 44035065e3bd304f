"""`bbbench list`: the suite's tasks as a table; `bbbench list TASK`: one task in full."""

from __future__ import annotations

import argparse

import bbbench
from bbbench.cli.common import UsageError
from bbbench.tasks.suite import latest_version


def add_parser(commands) -> None:
    listing = commands.add_parser(
        "list",
        help="print the suite's tasks as a table, or one task in full",
        description="Print the suite's tasks as a table; given a task ID, print that task's "
        "description and version history.",
    )
    listing.add_argument("task", nargs="?", metavar="TASK", help="a task ID to describe")
    listing.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    if args.task is not None:
        describe(args.task)
        return
    specs = [bbbench.spec(task_id) for task_id in bbbench.list_tasks()]
    rows = [
        (
            "task",
            "robot",
            "bots",
            "steps",
            "dt (s)",
            "max return",
            "eval seeds",
            "fingerprint",
            "summary",
        )
    ]
    rows += [
        (
            spec.id,
            "+".join(spec.robots) if spec.mixed else spec.robot,
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


def describe(task_id: str) -> None:
    """One task as its row says: summary, description, version history, fingerprint."""
    try:
        spec = bbbench.spec(task_id)
    except ValueError as error:
        raise UsageError(str(error)) from None
    newer = latest_version(spec.id)
    print(f"{spec.id}: {spec.summary}")
    if newer != spec.id:
        print(f"(superseded by {newer})")
    print(f"\n{spec.description.strip()}\n")
    bots = spec.group.n_bots if spec.multi_agent else 1
    robot = " and ".join(spec.robots) if spec.mixed else spec.robot
    print(
        f"robot {robot}, scenario {spec.scenario} ({spec.scenario_class.summary}), "
        f"bots {bots}, {spec.max_episode_steps} steps of "
        f"{spec.control_dt:g} s, max return {spec.max_return:g}, "
        f"{len(spec.eval_seeds)} eval seeds, fingerprint {spec.fingerprint}"
    )
    print("\nVersion history:")
    for entry in spec.version_history:
        print(f"  - {entry}")

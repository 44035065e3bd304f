"""`bbbench dev`: the maintenance tools (`bbbench.dev`), for the suite's developers."""

from __future__ import annotations

import argparse

from bbbench.tasks.suite import spec


def add_parser(commands) -> None:
    dev = commands.add_parser(
        "dev",
        help="maintenance tools: golden-rollout hashes, the random policy's reference returns",
        description="Tools for the suite's developers (bbbench.dev).",
    )
    tools = dev.add_subparsers(dest="tool", required=True, metavar="TOOL")
    golden = tools.add_parser(
        "golden",
        help="each task ID's golden-rollout hashes now, against bbbench/tasks/golden.json",
    )
    golden.add_argument(
        "--add", action="store_true", help="store the IDs golden.json lacks (never changes one)"
    )
    golden.set_defaults(run=run_golden)
    reference = tools.add_parser(
        "random-reference",
        help="the random policy's mean return on each task's eval seeds, against the stored one",
    )
    reference.add_argument("--workers", type=int, help="worker processes (default: every core)")
    reference.set_defaults(run=run_random_reference)


def run_golden(args: argparse.Namespace) -> None:
    from bbbench.dev import golden  # lazy: bbbench.dev

    for line in golden.report(add=args.add):
        print(line)


def run_random_reference(args: argparse.Namespace) -> None:
    from bbbench.dev.random_reference import measure  # lazy: bbbench.dev.random_reference

    for task_id, value in measure(workers=args.workers).items():
        print(f"{task_id:30} measured {value!r:22} stored {spec(task_id).random_return!r}")

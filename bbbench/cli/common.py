"""What the commands share: the user-mistake exception, checks, and the results table."""

from __future__ import annotations

import inspect
import sys

from rich.table import Table

from bbbench.policies.registry import BUILTIN_POLICIES


class UsageError(Exception):
    """A mistake in what the user asked for: reported in one line, exit code 2."""


def check_seed(value: int, flag: str = "--seed") -> int:
    if value < 0:
        raise UsageError(f"{flag} {value}: an episode seed is a whole number >= 0")
    return value


def add_play_options(parser, episodes: str | None = None) -> None:
    """The options of every command that plays episodes: `--episodes` (when `episodes`
    says which it plays), `--workers`, `--backend` and `--address`."""
    if episodes is not None:
        parser.add_argument("--episodes", type=int, help=episodes)
    parser.add_argument("--workers", type=int, help="worker processes (default: every core)")
    parser.add_argument("--backend", choices=("local", "ray"), default="local")
    parser.add_argument("--address", help="a Ray cluster's address (default: a local Ray)")


def add_contract_options(parser) -> None:
    """`--observation` and `--action-space`: the contract of an ONNX file without one."""
    parser.add_argument(
        "--observation",
        type=int,
        metavar="N",
        help="an ONNX file without a bbbench contract: the observation width it reads (5, "
        "16 with the height scan, 17 multi-bot, 19 team tasks ...)",
    )
    parser.add_argument(
        "--action-space",
        metavar="SPACE",
        help="an ONNX file without a bbbench contract: its action space as Gymnasium prints "
        "it ('Discrete(9)', 'Box(-1.0, 1.0, (1,), float32)')",
    )


def contract_options(args) -> dict:
    """The keywords of `load_policy` for `add_contract_options`' flags."""
    return {"observation": args.observation, "action_space": args.action_space}


def check_play_options(args) -> None:
    """`--episodes`, `--workers` and `--address` as every command that plays takes them."""
    if args.episodes is not None and args.episodes < 1:
        raise UsageError(f"--episodes must be at least 1, got {args.episodes}")
    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers must be at least 1, got {args.workers}")
    if args.address and args.backend != "ray":
        raise UsageError("--address names a Ray cluster: use it with --backend ray")


def say_normalization(policy) -> None:
    if policy.normalization_source:
        print(f"bbbench: {policy.normalization_source}", file=sys.stderr)


def results_table(document: dict) -> Table:
    policy = document["policy"]
    title = (
        f"{policy['name']} ({policy['algorithm']}, {policy['action_mode']} actions, "
        f"{'deterministic' if document['deterministic'] else 'sampled'})"
    )
    table = Table(title=title, title_justify="left")
    table.add_column("task", no_wrap=True)
    for column in ("episodes", "mean [95% CI]", "IQM", "success", "normalized"):
        table.add_column(column, justify="right", no_wrap=True)
    for task in document["tasks"]:
        score = task["aggregate"]
        if not score["episodes"]:
            table.add_row(task["task"].removeprefix("bbbench/"), "0", "-", "-", "-", "-")
            continue
        low, high = score["mean_ci"]
        normalized = score["normalized_score"]
        table.add_row(
            task["task"].removeprefix("bbbench/"),
            str(score["episodes"]) + (f" (-{len(task['missing'])})" if task["missing"] else ""),
            f"{score['mean']:.2f} [{low:.2f}, {high:.2f}]",
            f"{score['iqm']:.2f}",
            f"{score['success_rate']:.0%}",
            "-" if normalized is None else f"{normalized:.3f}",
        )
    overall = document["overall"]
    if overall["tasks"] > 1:
        low, high = overall["normalized_ci"]
        table.caption = (
            f"Mean normalized score over {overall['tasks']} tasks: "
            f"{overall['normalized_score']:.3f} (95% CI {low:.3f} to {high:.3f})"
        )
    return table


def builtin_policies() -> list[str]:
    return sorted(BUILTIN_POLICIES)


def builtins_in_either_mode() -> list[str]:
    """The built-ins that take an action mode (their factory's `action_mode`)."""
    return sorted(
        name
        for name, factory in BUILTIN_POLICIES.items()
        if "action_mode" in inspect.signature(factory).parameters
    )

"""`bbbench sweep`: policies' scores at each value of one axis (a robustness profile)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from rich.console import Console
from rich.progress import MofNCompleteColumn, Progress
from rich.table import Table

import bbbench
from bbbench.cli.common import (
    UsageError,
    add_play_options,
    check_play_options,
    say_normalization,
)
from bbbench.files import check_distinct_outputs, check_output_path, write_atomic
from bbbench.policies import PolicyError, load_policy
from bbbench.policies.errors import NoContract
from bbbench.portable import total

PLOT_FORMATS = (".svg", ".png")


def add_parser(commands) -> None:
    from bbbench.evaluation.sweep import AXES  # lazy: bbbench.evaluation

    sweep = commands.add_parser(
        "sweep",
        help="score policies at each value of one axis: a robustness profile",
        description="Play the same evaluation seeds at each value of one axis and report, per "
        "value, the aggregate of the results document, and per task the robustness score "
        "(the mean normalized score over the values) and the worst case (their minimum). "
        f"Axes: {', '.join(AXES)}. Without --values, the axis's standard grid; without "
        "--task, the robot's profile task for a perturbation (VelocityTracking for the "
        "two-wheel bot, LeggedVelocityTracking for the wheel-legged robot, SteerTracking for "
        "the steering robot), the terrain tasks for difficulty and "
        "for n_bots the multi-bot tasks that take 2 to 16 bots, or else those the policies "
        "fit (each the latest version the policies fit).",
    )
    sweep.add_argument(
        "policy",
        nargs="+",
        metavar="POLICY",
        help="a .zip, an ONNX file with its contract (bbbench export), or a built-in; several "
        "to overlay",
    )
    sweep.add_argument("--axis", required=True, help="the parameter to vary")
    sweep.add_argument(
        "--values",
        metavar="V1,V2,...",
        help="the values to play (default: the standard grid; on n_bots, the values of "
        "2, 4, 8, 16 every task takes)",
    )
    sweep.add_argument("--task", action="extend", nargs="+", metavar="ID", help="task ID(s)")
    add_play_options(sweep, episodes="the first N eval seeds at each value (default: all)")
    sweep.add_argument("--json", metavar="OUT", help="write the sweep document here")
    sweep.add_argument(
        "--plot", metavar="OUT", help="draw normalized score against the axis (.svg or .png)"
    )
    sweep.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from bbbench.evaluation.results import dumps  # lazy: bbbench.evaluation.results
    from bbbench.evaluation.sweep import sweep  # lazy: bbbench.evaluation.sweep

    policies, axis, values, task_ids = _checked(args)
    console = Console(stderr=True)
    pairs = len(values) * len(task_ids)
    with Progress(
        *Progress.get_default_columns(),
        MofNCompleteColumn(),
        console=console,
        transient=True,
        disable=not console.is_terminal,
    ) as progress:
        planned = args.episodes_per_pair * pairs * len(policies)
        bar = progress.add_task(f"{axis}: {pairs} (value, task) pair(s)", total=planned)
        try:
            document = sweep(
                policies,
                axis,
                values,
                task_ids,
                episodes=args.episodes,
                workers=args.workers,
                backend=args.backend,
                address=args.address,
                on_result=lambda count, played: progress.advance(bar, count),
            )
        except PolicyError as error:
            raise UsageError(str(error)) from None
        except ConnectionError as error:
            raise UsageError(f"--address {args.address}: {error}") from None
    out = Console() if Console().is_terminal else Console(width=120)
    labels = distinct_labels(args.policy)
    for entry, label in zip(document["policies"], labels, strict=True):
        out.print(_table(document, entry, label))
    if args.json is not None:
        write_atomic(args.json, dumps(document).encode())
        args.written.append(args.json)
        print(f"wrote {args.json}")
    if args.plot is not None:
        write_atomic(args.plot, _plot(document, labels, Path(args.plot).suffix.lower()))
        args.written.append(args.plot)
        print(f"wrote {args.plot}")
    missing = total(
        len(point["missing"])
        for entry in document["policies"]
        for task in entry["tasks"]
        for point in task["points"]
    )
    if missing:
        print(f"bbbench: {missing} episode(s) missing, their worker died twice", file=sys.stderr)
        return 1
    return 0


def _checked(args: argparse.Namespace):
    """The policies, the axis, its values and the tasks, every pair checked before any
    episode is played."""
    from bbbench.evaluation import select_tasks  # lazy: bbbench.evaluation
    from bbbench.evaluation.backends import check_ray  # lazy: bbbench.evaluation.backends
    from bbbench.evaluation.sweep import (  # lazy: bbbench.evaluation.sweep
        check_axis,
        parse_values,
        standard_grid,
        sweep_tasks,
    )

    check_play_options(args)
    try:
        axis = check_axis(args.axis)
        values = None if args.values is None else parse_values(axis, args.values)
        check_distinct_outputs({"--json": args.json, "--plot": args.plot})
        if args.json is not None:
            check_output_path(args.json, "--json")
        if args.plot is not None:
            check_output_path(args.plot, "--plot")
            if Path(args.plot).suffix.lower() not in PLOT_FORMATS:
                raise ValueError(
                    f"--plot {args.plot}: the figure is written as .svg or .png, by its name"
                )
        if args.backend == "ray":
            check_ray(args.address)
        check_distinct_policies(args.policy)
        policies = [load_policy(name) for name in args.policy]
        requested = args.task or _default_tasks(axis, policies)
        if values is None:  # the grid every task takes (on n_bots, a team's is 2 and 4)
            values = standard_grid(axis, [bbbench.spec(task_id).id for task_id in requested])
        for policy in policies:  # each fits every task, and every pair can be made
            task_ids = select_tasks(policy, requested)
            sweep_tasks(task_ids, axis, values, policy.height_scan)
    except NoContract as error:
        raise UsageError(error.for_file_only()) from None
    except (PolicyError, ValueError) as error:
        raise UsageError(str(error)) from None
    for policy in policies:
        say_normalization(policy)
    most = min(len(bbbench.spec(task_id).eval_seeds) for task_id in task_ids)
    if args.episodes is not None and args.episodes > most:
        raise UsageError(f"--episodes {args.episodes}: the tasks have {most} eval seeds each")
    args.episodes_per_pair = args.episodes or most
    return policies, axis, list(values), task_ids


def _default_tasks(axis: str, policies) -> list[str]:
    """The tasks the axis is swept on when none is given."""
    from bbbench.evaluation.sweep import (  # lazy: bbbench.evaluation.sweep
        applying_tasks,
        most_bots,
        standard_grid,
    )
    from bbbench.policies.policy import fitting_tasks  # lazy: bbbench.policies

    if axis not in ("difficulty", "n_bots"):
        # The task the robustness profile plays: VelocityTracking for the two-wheel bot,
        # LeggedVelocityTracking for the wheel-legged robot (the latest versions).
        from bbbench.evaluation.profile import profile_task  # lazy: bbbench.evaluation.profile

        tasks = {profile_task(policy) for policy in policies}
        if len(tasks) != 1 or None in tasks:
            raise ValueError(
                f"the policies are profiled on different tasks ({', '.join(map(str, tasks))}), "
                "or none: give --task"
            )
        return list(tasks)
    applies = applying_tasks(axis)
    fits = [t for t in applies if all(t in fitting_tasks(policy) for policy in policies)]
    if axis == "n_bots":  # those that take the whole grid, where the policies fit one
        whole = [t for t in fits if most_bots(bbbench.spec(t)) >= max(standard_grid(axis))]
        fits = whole or fits
    if not fits:
        kind = "terrain" if axis == "difficulty" else "multi-bot"
        raise ValueError(
            f"{axis} applies to the {kind} tasks ({', '.join(applies)}), and the policies do "
            "not all fit one of them: give --task"
        )
    return fits


def _table(document: dict, entry: dict, label: str) -> Table:
    policy = entry["policy"]
    title = (
        f"{label} ({policy['algorithm']}): normalized score [95% CI] by "
        f"{document['axis']} ({document['unit']})"
    )
    table = Table(title=title, title_justify="left", min_width=len(title))
    table.add_column(document["axis"], justify="right", no_wrap=True)
    for task in entry["tasks"]:
        table.add_column(task["task"].removeprefix("bbbench/"), justify="right", no_wrap=True)
    for row, value in enumerate(document["values"]):
        cells = []
        for task in entry["tasks"]:
            score = task["points"][row]["aggregate"]
            normalized = score.get("normalized_score")
            if normalized is None:
                cells.append("-" if not score["episodes"] else f"{score['mean']:.2f} (return)")
                continue
            low, high = score["normalized_ci"]
            cells.append(f"{normalized:.3f} [{low:.3f}, {high:.3f}]")
        table.add_row(f"{value:g}", *cells)
    over = "the standard grid" if document["standard_grid"] else "these values"
    lines = []
    for task in entry["tasks"]:
        robustness = task["robustness"]
        if robustness is not None:
            lines.append(
                f"{task['task'].removeprefix('bbbench/')}: robustness {robustness['score']:.3f}, "
                f"worst case {robustness['worst_case']:.3f} at {robustness['worst_value']:g}"
            )
    if lines:
        table.caption = f"Over {over}: " + "; ".join(lines)
        table.caption_justify = "left"
    return table


def _plot(document: dict, labels: list[str], suffix: str) -> bytes:
    from bbbench.leaderboard.plots import png_bytes, score_curves, svg_text  # lazy: matplotlib

    panels = []
    for i, task_id in enumerate(t["task"] for t in document["policies"][0]["tasks"]):
        lines = []
        for entry, label in zip(document["policies"], labels, strict=True):
            points = entry["tasks"][i]["points"]
            scored = [p for p in points if p["aggregate"].get("normalized_score") is not None]
            lines.append(
                (
                    label,
                    [p["value"] for p in scored],
                    [p["aggregate"]["normalized_score"] for p in scored],
                    [p["aggregate"]["normalized_ci"][0] for p in scored],
                    [p["aggregate"]["normalized_ci"][1] for p in scored],
                )
            )
        panels.append(
            {
                "title": task_id.removeprefix("bbbench/"),
                "xlabel": f"{document['axis']} ({document['unit']})",
                "lines": lines,
            }
        )
    figure = score_curves(panels)
    return svg_text(figure).encode() if suffix == ".svg" else png_bytes(figure)


def distinct_labels(given: list[str]) -> list[str]:
    """The policies as given (built-in names, paths), each by as few of its path's last
    parts as tell it from the others: `a/policy.zip` and `b/policy.zip`, not `policy.zip`
    twice (every board entry's file is `policy.*`)."""
    parts = [Path(name).parts or (name,) for name in given]
    for count in range(1, max(map(len, parts), default=1) + 1):
        labels = [str(Path(*p[-count:])) for p in parts]
        if len(set(labels)) == len(labels):
            return labels
    return list(given)


def check_distinct_policies(names: list[str]) -> None:
    """`ValueError` for a policy given twice (by name, or two paths to one file): it would
    be played twice and shown as two entries."""
    seen: dict[str, str] = {}
    for name in names:
        key = os.path.realpath(name) if os.path.exists(name) else name
        if key in seen:
            raise ValueError(
                f"{name} is given twice (as {seen[key]} and {name}): give each policy once"
                if seen[key] != name
                else f"{name} is given twice: give each policy once"
            )
        seen[key] = name

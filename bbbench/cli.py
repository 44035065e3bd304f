"""The `bbbench` command: parses, calls, prints."""

from __future__ import annotations

import argparse
import os
import statistics
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NoReturn

import numpy as np
from rich.console import Console
from rich.progress import MofNCompleteColumn, Progress
from rich.table import Table

import bbbench
from bbbench.files import write_atomic
from bbbench.policies import PDController
from bbbench.tasks.spec import episode_streams
from bbbench.terrain import HeightfieldTerrain

USAGE_ERROR = 2  # exit code for user mistakes, as argparse uses


class UsageError(Exception):
    """A mistake in what the user asked for: reported in one line, exit code 2."""


def _policy(name: str, env) -> Callable[[np.ndarray], object]:
    if name == "pd":
        return PDController(action_mode=env.unwrapped.action_mode)
    if name == "zero":
        zero = 4 if env.unwrapped.action_mode == "discrete" else np.zeros(1, np.float32)
        return lambda observation: zero
    if name == "random":
        return lambda observation: env.action_space.sample()
    raise UsageError(f"unknown policy {name!r}; expected one of pd, zero, random")


def cmd_list(args: argparse.Namespace) -> None:
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
            spec.summary,
        )
        for spec in specs
    ]
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    for row in rows:
        print(
            "  ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True)).rstrip()
        )


def cmd_rollout(args: argparse.Namespace) -> None:
    try:
        spec = bbbench.spec(args.task)
    except ValueError as error:
        raise UsageError(str(error)) from None
    if args.episodes < 1:
        raise UsageError(f"--episodes must be at least 1, got {args.episodes}")
    if spec.multi_agent:
        raise UsageError(
            f"{spec.id} is a multi-bot task and rollout plays single-bot tasks: "
            f"choose one of {', '.join(bbbench.list_tasks(multi_agent=False))}, or play it "
            f"from Python with bbbench.make_parallel({spec.id!r})"
        )
    env = bbbench.make(spec.id, action_mode=args.action_mode)
    policy = _policy(args.policy, env)
    env.action_space.seed(args.seed)
    print(
        f"{spec.id}: {args.episodes} episode(s) of the {args.policy!r} policy, "
        f"seeds {args.seed}..{args.seed + args.episodes - 1}"
    )
    print(f"{'seed':>8}  {'steps':>5}  {'return':>8}  ended by")
    returns, lengths = [], []
    for seed in range(args.seed, args.seed + args.episodes):
        observation, _ = env.reset(seed=seed)
        total, steps, terminated, truncated = 0.0, 0, False, False
        while not (terminated or truncated):
            observation, reward, terminated, truncated, _ = env.step(policy(observation))
            total += reward
            steps += 1
        returns.append(total)
        lengths.append(steps)
        print(f"{seed:>8}  {steps:>5}  {total:>8.2f}  {'fall' if terminated else 'time limit'}")
    env.close()
    print(
        f"mean return {statistics.fmean(returns):.2f} of at most {spec.max_return:g}; "
        f"mean length {statistics.fmean(lengths):.0f} of {spec.max_episode_steps} steps; "
        f"{sum(n == spec.max_episode_steps for n in lengths)}/{len(lengths)} "
        f"episodes reached the time limit"
    )


def cmd_terrain(args: argparse.Namespace) -> None:
    try:
        spec = bbbench.spec(args.task)
        if args.difficulty is not None:
            spec = spec.with_difficulty(args.difficulty)
    except (ValueError, TypeError) as error:
        raise UsageError(str(error)) from None
    if not isinstance(spec.terrain, HeightfieldTerrain):
        terrain_tasks = [t for t in bbbench.list_tasks() if bbbench.spec(t).difficulty is not None]
        raise UsageError(
            f"{spec.id} is on flat ground: there is no terrain to write. Tasks with terrain: "
            f"{', '.join(terrain_tasks)}"
        )
    from bbbench.terrain.mesh import export  # trimesh: only this command needs it

    heightmap = spec.terrain.generate(episode_streams(args.seed).terrain)
    try:
        path = export(heightmap, args.out)
    except (ValueError, OSError) as error:
        raise UsageError(str(error)) from None
    low, high = float(heightmap.heights.min()), float(heightmap.heights.max())
    print(
        f"wrote {path}: {spec.id} (difficulty {spec.difficulty:g}), episode seed {args.seed}, "
        f"{heightmap.extent[0]:g} x {heightmap.extent[1]:g} m, heights {low:.3f}..{high:.3f} m"
    )


def cmd_eval(args: argparse.Namespace) -> int:
    # Imported here: `bbbench list` should not pay for torch.
    from bbbench import evaluation
    from bbbench.evaluation.video import check_video_path, record_episode
    from bbbench.policies import PolicyError, load_policy

    if args.episodes is not None and args.episodes < 1:
        raise UsageError(f"--episodes must be at least 1, got {args.episodes}")
    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers must be at least 1, got {args.workers}")
    if args.address and args.backend != "ray":
        raise UsageError("--address names a Ray cluster: use it with --backend ray")
    if args.backend == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise UsageError("--backend ray needs Ray: pip install 'bbbench[ray]'") from None
    if args.json is not None and not Path(args.json).parent.is_dir():
        raise UsageError(f"--json {args.json}: no directory {Path(args.json).parent}")
    try:
        if args.video is not None:
            check_video_path(args.video)
        policy = load_policy(args.policy)
        task_ids = evaluation.select_tasks(policy, args.task)
    except (PolicyError, ValueError) as error:
        raise UsageError(str(error)) from None
    most = min(len(bbbench.spec(task_id).eval_seeds) for task_id in task_ids)
    if args.episodes is not None and args.episodes > most:
        raise UsageError(f"--episodes {args.episodes}: the tasks have {most} eval seeds each")

    per_task = args.episodes or most
    total = per_task * len(task_ids)
    console = Console(stderr=True)
    with Progress(
        *Progress.get_default_columns(),
        MofNCompleteColumn(),
        console=console,
        transient=True,
        disable=not console.is_terminal,
    ) as progress:
        bar = progress.add_task(f"{policy.name}: {len(task_ids)} task(s)", total=total)
        try:
            result = evaluation.evaluate(
                policy,
                task_ids,
                episodes=args.episodes,
                workers=args.workers,
                backend=args.backend,
                address=args.address,
                stochastic=args.stochastic,
                on_result=lambda count, played: progress.advance(bar, count),
            )
        except PolicyError as error:  # its network cannot be built for a task's spaces
            raise UsageError(str(error)) from None
    document = result.document
    out = Console()
    if not out.is_terminal:  # a pipe or a file: wide enough that nothing is cut
        out = Console(width=120)
    out.print(_results_table(document))
    if args.json is not None:
        write_atomic(args.json, evaluation.dumps(document).encode())
        print(f"wrote {args.json}")
    if args.video is not None:
        task_id = task_ids[0]
        seed = bbbench.spec(task_id).eval_seeds[0]
        frames = record_episode(policy, task_id, seed, args.video, stochastic=args.stochastic)
        print(f"wrote {args.video}: {task_id}, episode seed {seed}, {frames} frames")
    if result.missing:
        missing = ", ".join(f"{task_id} seed {seed}" for task_id, seed in result.missing)
        print(
            f"bbbench: {len(result.missing)} episode(s) missing, their worker died twice: "
            f"{missing}",
            file=sys.stderr,
        )
        return 1
    return 0


def _results_table(document: dict) -> Table:
    policy = document["policy"]
    title = (
        f"{policy['name']} ({policy['algorithm']}, {policy['action_mode']} actions, "
        f"{'deterministic' if document['deterministic'] else 'stochastic'})"
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
        low, high = overall["normalized_iqm_ci"]
        table.caption = (
            f"IQM of normalized scores over {overall['tasks']} tasks: "
            f"{overall['normalized_iqm']:.3f} (95% CI {low:.3f} to {high:.3f})"
        )
    return table


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="bbbench", description="A benchmark suite for two-wheeled balancing robots."
    )
    parser.add_argument("--version", action="version", version=f"bbbench {bbbench.__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    listing = commands.add_parser("list", help="print the suite's tasks as a table")
    listing.set_defaults(run=cmd_list)

    rollout = commands.add_parser(
        "rollout", help="run a built-in policy on a task and print a summary"
    )
    rollout.add_argument("--task", default="bbbench/FlatBalance-v0", help="task ID")
    rollout.add_argument(
        "--policy",
        default="pd",
        choices=("pd", "zero", "random"),
        help="pd: the PD baseline; zero: never change the wheel command; random: uniform actions",
    )
    rollout.add_argument("--episodes", type=int, default=5, help="episodes to run (default 5)")
    rollout.add_argument("--seed", type=int, default=0, help="seed of the first episode")
    rollout.add_argument(
        "--action-mode",
        default="discrete",
        choices=("discrete", "continuous"),
        help="the env's action mode",
    )
    rollout.set_defaults(run=cmd_rollout)

    terrain = commands.add_parser(
        "terrain", help="write the terrain of a task's episode seed as a mesh (.obj, .stl, ...)"
    )
    terrain.add_argument("--task", default="bbbench/Bumps-v0", help="a task with terrain")
    terrain.add_argument("--seed", type=int, default=0, help="episode seed (default 0)")
    terrain.add_argument("--difficulty", type=float, help="in [0, 1]; default: the task's")
    terrain.add_argument("--out", required=True, help="output file: .obj, .stl, .ply or .glb")
    terrain.set_defaults(run=cmd_terrain)

    evaluate = commands.add_parser(
        "eval",
        help="score a policy on the suite's fixed evaluation seeds",
        description="Score a policy on the suite's fixed evaluation seeds: every task it fits, "
        "or those given with --task. POLICY is a stable-baselines3 .zip (read without "
        "unpickling anything) or a built-in: reference (the default, a PPO policy shipped "
        "with bbbench), pd, random.",
    )
    evaluate.add_argument("policy", nargs="?", default="reference", metavar="POLICY")
    evaluate.add_argument(
        "--task", action="extend", nargs="+", metavar="ID", help="task ID(s); default: all it fits"
    )
    evaluate.add_argument(
        "--episodes", type=int, help="the first N eval seeds of each task (default: all)"
    )
    evaluate.add_argument("--workers", type=int, help="worker processes (default: every core)")
    evaluate.add_argument("--backend", choices=("local", "ray"), default="local")
    evaluate.add_argument("--address", help="a Ray cluster's address (default: a local Ray)")
    evaluate.add_argument("--json", metavar="OUT", help="write the results document here")
    evaluate.add_argument(
        "--video", metavar="OUT", help="write the first task's first episode (.gif or .mp4)"
    )
    evaluate.add_argument(
        "--stochastic", action="store_true", help="sample actions (default: deterministic)"
    )
    evaluate.set_defaults(run=cmd_eval)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """The `bbbench` command; with `argv` None it reads the process's arguments."""
    args = build_parser().parse_args(argv)
    try:
        return args.run(args) or 0
    except UsageError as error:
        print(f"bbbench: error: {error}", file=sys.stderr)
        return USAGE_ERROR


def run() -> NoReturn:
    """The `bbbench` process (the console script, `python -m bbbench`): `main()`, then
    exit at once.

    By then every file the command writes is closed (written atomically) and its
    workers or Ray are stopped; skipping the interpreter's teardown saves some
    0.2 s once `eval` has imported torch. An exception, or argparse's own exit,
    leaves the usual way.
    """
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    run()

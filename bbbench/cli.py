"""The `bbbench` command: parses, calls, prints."""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import sys
from collections.abc import Sequence
from typing import NoReturn

from rich.console import Console
from rich.progress import MofNCompleteColumn, Progress
from rich.table import Table
from rich.text import Text

import bbbench
from bbbench.files import check_output_path, write_atomic
from bbbench.tasks.spec import episode_streams
from bbbench.terrain import HeightfieldTerrain

USAGE_ERROR = 2  # exit code for user mistakes, as argparse uses


class UsageError(Exception):
    """A mistake in what the user asked for: reported in one line, exit code 2."""


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


def _seed(value: int, flag: str = "--seed") -> int:
    if value < 0:
        raise UsageError(f"{flag} {value}: an episode seed is a whole number >= 0")
    return value


def cmd_rollout(args: argparse.Namespace) -> None:
    from bbbench.evaluation.episodes import action_generator
    from bbbench.policies import PolicyError, load_policy
    from bbbench.policies.base import act_once

    try:
        spec = bbbench.spec(args.task)
    except ValueError as error:
        raise UsageError(str(error)) from None
    if args.episodes < 1:
        raise UsageError(f"--episodes must be at least 1, got {args.episodes}")
    _seed(args.seed)
    if spec.multi_agent:
        raise UsageError(
            f"{spec.id} is a multi-bot task and rollout plays single-bot tasks: "
            f"choose one of {', '.join(bbbench.list_tasks(multi_agent=False))}, or play it "
            f"from Python with bbbench.make_parallel({spec.id!r})"
        )
    try:
        policy = load_policy(
            args.policy, vecnormalize=args.vecnormalize, action_mode=args.action_mode
        )
        if policy.mismatch(spec.id):
            raise PolicyError(f"{policy.name} ({policy.spaces_text()}) cannot play {spec.id}")
        actor = policy.actor(spec.id)
    except PolicyError as error:
        raise UsageError(str(error)) from None
    _say_normalization(policy)
    env = bbbench.make(spec.id, action_mode=policy.action_mode, **policy.env_options())
    acting = "random actions" if policy.random_actions else "deterministic"
    print(
        f"{spec.id}: {args.episodes} episode(s) of the {policy.name!r} policy ({acting}), "
        f"seeds {args.seed}..{args.seed + args.episodes - 1}"
    )
    print(f"{'seed':>8}  {'steps':>5}  {'return':>8}  ended by")
    returns, lengths = [], []
    for seed in range(args.seed, args.seed + args.episodes):
        observation, _ = env.reset(seed=seed)
        rng = action_generator(seed) if policy.random_actions else None
        total, steps, ended = 0.0, 0, None
        while ended is None:
            action = act_once(actor, observation, rng)
            if action is None:
                ended = "NaN action"
                break
            observation, reward, terminated, truncated, _ = env.step(action)
            total += reward
            steps += 1
            ended = "fall" if terminated else "time limit" if truncated else None
        returns.append(total)
        lengths.append(steps)
        print(f"{seed:>8}  {steps:>5}  {total:>8.2f}  {ended}")
    env.close()
    print(
        f"mean return {statistics.fmean(returns):.2f} of at most {spec.max_return:g}; "
        f"mean length {statistics.fmean(lengths):.0f} of {spec.max_episode_steps} steps; "
        f"{sum(n == spec.max_episode_steps for n in lengths)}/{len(lengths)} "
        f"episodes reached the time limit"
    )


def _say_normalization(policy) -> None:
    if policy.normalization_source:
        print(f"bbbench: {policy.normalization_source}", file=sys.stderr)


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

    heightmap = spec.terrain.generate(episode_streams(_seed(args.seed)).terrain)
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
    from bbbench.evaluation.backends import check_ray_address, default_workers
    from bbbench.evaluation.video import check_video_path, record_episode
    from bbbench.policies import PolicyError, load_policy

    if args.episodes is not None and args.episodes < 1:
        raise UsageError(f"--episodes must be at least 1, got {args.episodes}")
    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers must be at least 1, got {args.workers}")
    if args.address and args.backend != "ray":
        raise UsageError("--address names a Ray cluster: use it with --backend ray")
    cores = default_workers()
    if args.workers is not None and args.workers > cores and not args.address:
        # evaluate() caps them; the command says so
        print(
            f"bbbench: --workers {args.workers} is more than the {cores} core(s) here: "
            f"using {cores}",
            file=sys.stderr,
        )
    try:  # everything the run will need, before any episode is played
        if args.json is not None:
            check_output_path(args.json, "--json")
        if args.video is not None:
            check_video_path(args.video)
        if args.backend == "ray":
            check_ray_address(args.address)
        policy = load_policy(args.policy, vecnormalize=args.vecnormalize)
        task_ids = evaluation.select_tasks(policy, args.task)
    except (PolicyError, ValueError) as error:
        raise UsageError(str(error)) from None
    _say_normalization(policy)
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
        except ConnectionError as error:  # Ray answered on the port, then failed
            raise UsageError(f"--address {args.address}: {error}") from None
    document = result.document
    out = Console()
    if not out.is_terminal:  # a pipe or a file: wide enough that nothing is cut
        out = Console(width=120)
    out.print(_results_table(document))
    if args.json is not None:
        write_atomic(args.json, evaluation.dumps(document).encode())
        args.written.append(args.json)
        print(f"wrote {args.json}")
    if args.video is not None:
        task_id = task_ids[0]
        seed = bbbench.spec(task_id).eval_seeds[0]
        frames = record_episode(policy, task_id, seed, args.video, stochastic=args.stochastic)
        args.written.append(args.video)
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
        low, high = overall["normalized_iqm_ci"]
        table.caption = (
            f"IQM of normalized scores over {overall['tasks']} tasks: "
            f"{overall['normalized_iqm']:.3f} (95% CI {low:.3f} to {high:.3f})"
        )
    return table


def _leaderboard_options(args: argparse.Namespace) -> dict:
    """The options every leaderboard command that plays episodes shares, checked."""
    from bbbench.evaluation.backends import check_ray_address

    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers must be at least 1, got {args.workers}")
    if args.address and args.backend != "ray":
        raise UsageError("--address names a Ray cluster: use it with --backend ray")
    if args.backend == "ray":
        try:
            check_ray_address(args.address)
        except ValueError as error:
            raise UsageError(str(error)) from None
    return {"workers": args.workers, "backend": args.backend, "address": args.address}


def _leaderboard_root(args: argparse.Namespace):
    from pathlib import Path

    root = Path(args.root)
    if not root.is_dir():
        raise UsageError(
            f"--root {args.root}: no such folder (run from the repository's top, or give the "
            f"leaderboard folder)"
        )
    return root


def _playing(what: str):
    """A live count of episodes played, on a terminal."""
    console = Console(stderr=True)
    progress = Progress(
        *Progress.get_default_columns()[:1],
        MofNCompleteColumn(),
        console=console,
        transient=True,
        disable=not console.is_terminal,
    )
    bar = progress.add_task(what, total=None)
    return progress, lambda count: progress.advance(bar, count)


def cmd_leaderboard_build(args: argparse.Namespace) -> int:
    from bbbench import leaderboard

    root = _leaderboard_root(args)
    options = _leaderboard_options(args)
    progress, on_episodes = _playing("episodes played")
    try:
        with progress:
            built = leaderboard.build(
                root,
                leaderboard.DEFAULT_BOARD,
                cache=not args.no_cache,
                on_episodes=on_episodes,
                **options,
            )
    except leaderboard.SubmissionError as error:
        raise UsageError(str(error)) from None
    except leaderboard.BuildError as error:
        print(f"bbbench: {error}; nothing written", file=sys.stderr)
        return 1
    args.written.append(str(root))
    tracks = ", ".join(
        f"{len(track['entries'])} on the {track['track']}-bot track"
        for track in built.document["tracks"]
    )
    print(
        f"wrote {root}: {tracks}; {built.episodes} episodes ({built.played} played, "
        f"{built.episodes - built.played} from stored results)"
    )
    return 0


def cmd_leaderboard_check(args: argparse.Namespace) -> int:
    from bbbench import leaderboard

    root = _leaderboard_root(args)
    options = _leaderboard_options(args)
    progress, on_episodes = _playing("episodes re-scored")
    try:
        with progress:
            checked = leaderboard.check(
                root, leaderboard.DEFAULT_BOARD, on_episodes=on_episodes, **options
            )
    except leaderboard.SubmissionError as error:
        raise UsageError(str(error)) from None
    except leaderboard.BuildError as error:
        print(f"bbbench: {error}", file=sys.stderr)
        return 1
    if checked.problems:
        print(f"leaderboard check FAILED: {root} is not what its submissions give:")
        for problem in checked.problems:
            print(f"  {problem}")
        print("Rebuild with `bbbench leaderboard build` and commit what it writes.")
        return 1
    print(
        f"leaderboard check ok: {checked.entries} entries, {checked.tasks} tasks, "
        f"{checked.episodes} episodes re-scored, {checked.seconds:.0f} s"
    )
    return 0


def cmd_leaderboard_add(args: argparse.Namespace) -> int:
    from bbbench import leaderboard

    root = _leaderboard_root(args)
    options = _leaderboard_options(args)
    metadata = {
        "name": args.name,
        "authors": args.author,
        "algorithm": args.algorithm,
        **({"action_mode": args.action_mode} if args.action_mode else {}),
        "training": {
            "env_steps": args.env_steps,
            "wall_time": args.wall_time,
            "hardware": args.hardware,
        },
        "training_seeds": args.seeds,
        "command": args.training_command,
        **({"url": args.url} if args.url else {}),
        "licence": args.licence,
        **({"notes": args.notes} if args.notes else {}),
        **({"date": args.date} if args.date else {}),
    }
    progress, on_episodes = _playing("episodes played")
    try:
        with progress:
            built = leaderboard.add(
                root,
                args.policy,
                args.slug,
                metadata,
                vecnormalize=args.vecnormalize,
                board=leaderboard.DEFAULT_BOARD,
                on_episodes=on_episodes,
                **options,
            )
    except leaderboard.SubmissionError as error:
        raise UsageError(str(error)) from None
    except leaderboard.BuildError as error:
        print(f"bbbench: {error}; nothing written", file=sys.stderr)
        return 1
    args.written.append(str(root))
    for track in built.document["tracks"]:
        for entry in track["entries"]:
            if entry["slug"] == args.slug:
                print(
                    f"{track['track']}-bot track: {args.slug} ranks {entry['rank']} of "
                    f"{len(track['entries'])}"
                )
    print(
        f"wrote {root / 'submissions' / args.slug} and the board: {built.played} episodes "
        f"played, {built.episodes - built.played} from stored results. Commit both."
    )
    return 0


def cmd_leaderboard_show(args: argparse.Namespace) -> int:
    import json

    from bbbench.leaderboard import DOCUMENT
    from bbbench.leaderboard.views import rows

    path = _leaderboard_root(args) / DOCUMENT
    try:
        document = json.loads(path.read_bytes())
        tracks = [t for t in document["tracks"] if args.track in (None, t["track"])]
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise UsageError(
            f"{path}: not a leaderboard ({error}); run `bbbench leaderboard build`"
        ) from None
    out = Console()
    if not out.is_terminal:
        out = Console(width=200)
    for track in tracks:
        header, body = rows(track)
        table = Table(title=track["title"].capitalize(), title_justify="left")
        for i, column in enumerate(header):
            table.add_column(column, justify="left" if i in (1, 2) else "right")
        for row in body:
            table.add_row(*map(Text, row))  # submitted names are text, not rich markup
        out.print(table)
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    from rich.progress import BarColumn, TextColumn, TimeElapsedColumn

    from bbbench import training

    try:
        tasks, _, _ = training.check_request(args.task, args.algo, args.action_mode, args.steps)
        if args.n_envs is not None and args.n_envs < 1:
            raise ValueError(f"--n-envs must be at least 1, got {args.n_envs}")
        _seed(args.seed)
        check_output_path(args.out, "--out")
        if args.log is not None:
            from pathlib import Path

            log = Path(args.log)
            if log.exists() and not log.is_dir():
                raise ValueError(f"--log {args.log}: exists and is not a folder")
    except ValueError as error:
        raise UsageError(str(error)) from None
    console = Console(stderr=True)
    progress = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]}"),
        TextColumn("{task.fields[score]}"),
        TimeElapsedColumn(),
        console=console,
        transient=True,
        disable=not console.is_terminal,
    )
    bar = progress.add_task(
        f"{args.algo.upper()} {', '.join(tasks)}", total=None, rate="", score=""
    )
    began = [None]

    def on_progress(steps: int, total: int, point: dict | None) -> None:
        import time

        now = time.perf_counter()
        began[0] = began[0] or now
        rate = steps / (now - began[0]) if now > began[0] else 0.0
        fields = {"rate": f"{rate:,.0f} steps/s"}
        if point is not None:
            fields["score"] = f"eval mean {point['mean']:.1f}"
        progress.update(bar, completed=min(steps, total), total=total, **fields)

    with progress:
        trained = training.train(
            tasks,
            args.algo,
            out=args.out,
            action_mode=args.action_mode,
            steps=args.steps,
            seed=args.seed,
            n_envs=args.n_envs,
            log_dir=args.log,
            final_episodes=args.eval_episodes,
            on_progress=on_progress,
        )
    args.written.append(args.out)
    best = max(trained.curve, key=lambda point: point["mean"])
    out = Console()
    if not out.is_terminal:
        out = Console(width=120)
    out.print(_results_table(trained.results))
    print(
        f"wrote {args.out} (best at {best['steps']:,} steps: mean return {best['mean']:.1f} on "
        f"training seeds) and {trained.log_dir}/curve.json, curve.png, train.json, "
        f"results.json; {trained.seconds:.0f} s"
    )
    return 0


def _builtin_policies() -> list[str]:
    from bbbench.policies.base import BUILTIN_POLICIES

    return sorted(BUILTIN_POLICIES)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="bbbench", description="A benchmark suite for two-wheeled balancing robots."
    )
    parser.add_argument("--version", action="version", version=f"bbbench {bbbench.__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    listing = commands.add_parser("list", help="print the suite's tasks as a table")
    listing.set_defaults(run=cmd_list)

    rollout = commands.add_parser(
        "rollout", help="run a policy on a task's episodes and print a summary"
    )
    rollout.add_argument("--task", default="bbbench/FlatBalance-v0", help="task ID")
    rollout.add_argument(
        "--policy",
        default="pd",
        metavar="POLICY",
        help=f"a built-in ({', '.join(_builtin_policies())}) or a stable-baselines3 .zip "
        f"(default pd)",
    )
    rollout.add_argument("--episodes", type=int, default=5, help="episodes to run (default 5)")
    rollout.add_argument("--seed", type=int, default=0, help="seed of the first episode")
    rollout.add_argument(
        "--action-mode",
        choices=("discrete", "continuous"),
        help="the built-ins' action mode (default discrete; a zip's is its own)",
    )
    rollout.add_argument(
        "--vecnormalize", metavar="PKL", help="VecNormalize statistics the zip was trained with"
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
        f"with bbbench), {', '.join(p for p in _builtin_policies() if p != 'reference')}.",
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
        "--vecnormalize",
        metavar="PKL",
        help="the VecNormalize statistics (VecNormalize.save) the policy was trained with, "
        "read without unpickling; found on its own where rl-zoo3 saves them",
    )
    evaluate.add_argument(
        "--video", metavar="OUT", help="write the first task's first episode (.gif or .mp4)"
    )
    evaluate.add_argument(
        "--stochastic", action="store_true", help="sample actions (default: deterministic)"
    )
    evaluate.set_defaults(run=cmd_eval)

    trainer = commands.add_parser(
        "train",
        help="train a policy on a task with its shipped recipe (stable-baselines3)",
        description="Train a policy with the recipe shipped for the task (rl-zoo3 "
        "hyperparameter files in bbbench/training/recipes/). Several single-bot tasks "
        "train one generalist on all of them.",
    )
    trainer.add_argument("task", nargs="+", metavar="TASK", help="task ID(s)")
    trainer.add_argument("--algo", required=True, help="ppo, a2c, dqn, sac or td3")
    trainer.add_argument(
        "--action-mode",
        choices=("discrete", "continuous"),
        help="default: discrete for ppo, a2c and dqn; continuous for sac and td3",
    )
    trainer.add_argument("--steps", type=int, help="environment steps (default: the recipe's)")
    trainer.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    trainer.add_argument("--n-envs", type=int, help="parallel envs (default: the recipe's)")
    trainer.add_argument("--out", default="policy.zip", help="the policy zip (default policy.zip)")
    trainer.add_argument(
        "--log", help="folder for curve.json, curve.png, train.json (default: the zip's)"
    )
    trainer.add_argument(
        "--eval-episodes",
        type=int,
        help="eval seeds per task in the final table (default: all)",
    )
    trainer.set_defaults(run=cmd_train)

    board = commands.add_parser(
        "leaderboard",
        help="build, check, add to or show the leaderboard",
        description="The leaderboard: submissions in <root>/submissions, scored on every "
        "evaluation seed by the shipped harness, ranked with intervals.",
    )
    actions = board.add_subparsers(dest="action", required=True, metavar="ACTION")

    def with_common(parser: argparse.ArgumentParser, plays: bool = True):
        parser.add_argument(
            "--root", default="leaderboards", help="the leaderboard folder (default leaderboards)"
        )
        if plays:
            parser.add_argument(
                "--workers", type=int, help="worker processes (default: every core)"
            )
            parser.add_argument("--backend", choices=("local", "ray"), default="local")
            parser.add_argument("--address", help="a Ray cluster's address (default: a local Ray)")
        return parser

    building = with_common(
        actions.add_parser(
            "build", help="score every submission and write the board (JSON, Markdown, HTML)"
        )
    )
    building.add_argument(
        "--no-cache", action="store_true", help="play every episode again (ignore stored results)"
    )
    building.set_defaults(run=cmd_leaderboard_build)
    checking = with_common(
        actions.add_parser(
            "check",
            help="rebuild from scratch and fail (exit 1) if any checked-in file differs",
        )
    )
    checking.set_defaults(run=cmd_leaderboard_check)
    adding = with_common(
        actions.add_parser(
            "add",
            help="add a submission: check the policy, score it, write its folder and the board",
        )
    )
    adding.add_argument("policy", metavar="POLICY", help="a policy .zip, or a built-in's name")
    adding.add_argument("--slug", required=True, help="the entry's folder name, e.g. my-ppo")
    adding.add_argument("--name", required=True, help="display name")
    adding.add_argument("--algorithm", required=True, help="e.g. PPO")
    adding.add_argument(
        "--author", action="append", required=True, help="an author (repeat for several)"
    )
    adding.add_argument(
        "--action-mode",
        choices=("discrete", "continuous"),
        help="checked against the zip (default: the zip's; discrete for a built-in)",
    )
    adding.add_argument(
        "--env-steps", type=int, required=True, help="environment steps used in training"
    )
    adding.add_argument("--wall-time", required=True, help="training wall time, in words")
    adding.add_argument("--hardware", required=True, help="the training machine, in words")
    adding.add_argument(
        "--seeds", type=int, nargs="*", default=[], metavar="SEED", help="training seed(s)"
    )
    adding.add_argument(
        "--command",
        dest="training_command",
        required=True,
        help="the exact command or recipe that trained it",
    )
    adding.add_argument("--licence", required=True, help="the policy's licence (SPDX), e.g. MIT")
    adding.add_argument("--url", help="a paper, repository or write-up")
    adding.add_argument("--notes", help="anything else a reader should know")
    adding.add_argument("--date", help="the submission's own date, as you state it")
    adding.add_argument(
        "--vecnormalize", metavar="PKL", help="VecNormalize statistics the policy needs"
    )
    adding.set_defaults(run=cmd_leaderboard_add)
    showing = with_common(actions.add_parser("show", help="print the ranked tables"), plays=False)
    showing.add_argument("--track", choices=("single", "multi"), help="one track (default both)")
    showing.set_defaults(run=cmd_leaderboard_show)
    return parser


class Terminated(BaseException):
    """SIGTERM, raised where the process is, so that cleanup runs as for Ctrl-C."""


def main(argv: Sequence[str] | None = None) -> int:
    """The `bbbench` command; with `argv` None it reads the process's arguments."""
    args = build_parser().parse_args(argv)
    args.written = []  # files the command has written, for the message if interrupted
    try:
        return args.run(args) or 0
    except UsageError as error:
        print(f"bbbench: error: {error}", file=sys.stderr)
        return USAGE_ERROR
    except (KeyboardInterrupt, Terminated) as interruption:
        what = "interrupted" if isinstance(interruption, KeyboardInterrupt) else "terminated"
        kept = f"wrote {', '.join(args.written)} only" if args.written else "nothing written"
        print(f"bbbench: {what}; {kept}", file=sys.stderr)
        return 130 if isinstance(interruption, KeyboardInterrupt) else 143


def _terminate(signum, frame) -> NoReturn:
    raise Terminated


def run() -> NoReturn:
    """The `bbbench` process (the console script, `python -m bbbench`): `main()`, then
    exit at once.

    By then every file the command writes is closed (written atomically) and its
    workers or Ray are stopped; skipping the interpreter's teardown saves some
    0.2 s once `eval` has imported torch. An exception, or argparse's own exit,
    leaves the usual way. SIGTERM stops the command as Ctrl-C does (exit 143).
    """
    signal.signal(signal.SIGTERM, _terminate)
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    run()

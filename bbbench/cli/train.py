"""`bbbench train`: train a policy with the recipe shipped for its task."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from bbbench.cli.common import UsageError, check_seed, results_table


def add_parser(commands) -> None:
    trainer = commands.add_parser(
        "train",
        help="train a policy on a task with its shipped recipe (stable-baselines3; IPPO and "
        "MAPPO with BenchMARL)",
        description="Train a policy with the recipe shipped for the task (rl-zoo3 "
        "hyperparameter files in bbbench/training/recipes/; for IPPO and MAPPO on a "
        "multi-bot task, BenchMARL's YAML there, and an ONNX policy). Several single-bot "
        "tasks train one generalist on all of them.",
    )
    trainer.add_argument("task", nargs="+", metavar="TASK", help="task ID(s)")
    trainer.add_argument(
        "--algo",
        required=True,
        help="an algorithm with a recipe in bbbench/training/recipes/ (ppo.yml: --algo ppo; "
        "ippo and mappo train multi-bot tasks with BenchMARL: pip install 'bbbench[marl]')",
    )
    trainer.add_argument(
        "--recipe",
        metavar="FILE",
        help="a recipe file in the format of the algorithm's shipped one, instead of it",
    )
    trainer.add_argument(
        "--action-mode",
        choices=("discrete", "continuous"),
        help="default: the first the algorithm learns that the task's robot takes (PPO: "
        "discrete on the two-wheel bot, continuous on the wheel-legged robot; IPPO and "
        "MAPPO: their recipe's)",
    )
    trainer.add_argument(
        "--steps",
        type=int,
        help="environment steps (default: the recipe's; for IPPO and MAPPO, world steps: "
        "BenchMARL's frames, in each of which every bot acts)",
    )
    trainer.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    trainer.add_argument(
        "--seeds",
        metavar="S,S,...",
        help="train one policy per seed (e.g. 0,1,2), each into <out stem>-s<seed>/ beside --out",
    )
    trainer.add_argument(
        "--backend",
        choices=("local", "ray"),
        default="local",
        help="with --seeds: one after another here (local), or one Ray task each (ray)",
    )
    trainer.add_argument("--address", help="a Ray cluster's address (default: a local Ray)")
    trainer.add_argument("--n-envs", type=int, help="parallel envs (default: the recipe's)")
    trainer.add_argument(
        "--workers",
        type=int,
        help="IPPO and MAPPO: processes that step the worlds (default: the recipe's; the "
        "same result for any number)",
    )
    trainer.add_argument(
        "--out",
        help="the policy file (default policy.zip; policy.onnx for IPPO and MAPPO, and "
        "policy.zip, a team file, on a mixed team)",
    )
    trainer.add_argument(
        "--log", help="folder for curve.json, curve.png, train.json (default: the zip's)"
    )
    trainer.add_argument(
        "--eval-episodes",
        type=int,
        help="eval seeds per task in the final table (default: all)",
    )
    trainer.set_defaults(run=run)


def check_eval_episodes(episodes: int | None, task_ids: list[str]) -> None:
    """`ValueError` unless the final evaluation's episodes per task are 1 to the tasks'
    evaluation seeds: checked before a training, not after it."""
    from bbbench.tasks.suite import spec  # lazy: bbbench.tasks

    most = min(len(spec(task_id).eval_seeds) for task_id in task_ids)
    if episodes is not None and not 1 <= episodes <= most:
        raise ValueError(
            f"--eval-episodes {episodes}: expected 1 to {most} (the tasks' evaluation seeds; "
            f"leave it out to play them all)"
        )


def run(args: argparse.Namespace) -> int:
    from bbbench import training  # lazy: bbbench.training

    marl = args.algo in training.MARL_TRAINABLE
    if args.out is None:
        known = args.algo in training.ALGORITHMS  # an unknown one is refused below
        args.out = "policy" + (training.policy_suffix(args.algo, args.task) if known else ".zip")
    if args.seeds is not None:
        return _run_seeds(args)
    if args.backend != "local" or args.address is not None:
        raise UsageError("--backend and --address fan out --seeds: give --seeds 0,1,2")
    try:
        tasks, key, _ = training.check_request(
            args.task, args.algo, args.action_mode, args.steps, args.recipe
        )
        check_seed(args.seed)
        check_eval_episodes(args.eval_episodes, tasks)
        training.check_policy_path(args.algo, args.out, tasks)
        training.check_fresh(args.out, args.log)
        plan = training.recipe(args.algo, key, args.recipe)
        training.statistics_path(args.out, plan)
        _, _, note = training.check_collection(plan, tasks, args.n_envs, args.workers, args.steps)
        if args.log is not None:
            log = Path(args.log)
            if log.exists() and not log.is_dir():
                raise ValueError(f"--log {args.log}: exists and is not a folder")
            try:  # made now, so that a folder that cannot be made is said before training
                log.mkdir(parents=True, exist_ok=True)
            except OSError as error:
                raise ValueError(
                    f"--log {args.log}: cannot make the folder ({error.strerror}); give a "
                    f"folder you can write"
                ) from None
    except ValueError as error:
        raise UsageError(str(error)) from None
    console = Console(stderr=True)
    if note is not None:
        print(f"bbbench: {note}", file=sys.stderr)
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
        now = time.perf_counter()
        began[0] = began[0] or now
        rate = steps / (now - began[0]) if now > began[0] else 0.0
        fields = {"rate": f"{rate:,.0f} steps/s"}
        if point is not None:
            fields["score"] = f"eval mean {point['mean']:.1f}"
            if not console.is_terminal:  # a log file: one line per point of the curve
                console.print(
                    f"{steps:,} steps, {point['wall_time_s']:.0f} s: mean return "
                    f"{point['mean']:.2f} on training seeds (episode length "
                    f"{point['mean_length']:.0f})",
                    highlight=False,
                )
        progress.update(bar, completed=min(steps, total), total=total, **fields)

    with progress:
        try:
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
                recipe_file=args.recipe,
                workers=args.workers,
            )
        except training.StoppedTrainingError as error:  # said before anything is trained
            raise UsageError(str(error)) from None
    args.written.append(args.out)
    if trained.statistics is not None:
        args.written.append(str(trained.statistics))
    kept = trained.kept
    which = "the last policy" if kept is trained.curve[-1] and marl else "best"
    out = Console()
    if not out.is_terminal:
        out = Console(width=120)
    out.print(results_table(trained.results))
    statistics = f", its VecNormalize statistics {trained.statistics}" if trained.statistics else ""
    print(
        f"wrote {args.out}{statistics} ({which} at {kept['steps']:,} steps: mean return "
        f"{kept['mean']:.1f} on training seeds) and {trained.log_dir}/curve.json, curve.png, "
        f"train.json, results.json; {trained.seconds:.0f} s"
    )
    return 0


def _run_seeds(args: argparse.Namespace) -> int:
    """`--seeds`: one training per seed, here or on Ray; a line as each finishes."""
    from bbbench import training  # lazy: bbbench.training
    from bbbench.evaluation.backends import check_ray  # lazy: bbbench.evaluation
    from bbbench.training import fanout  # lazy: bbbench.training

    try:
        seeds = fanout.parse_seeds(args.seeds)
        if args.seed != 0:
            raise ValueError("--seed and --seeds: give one of them")
        if args.address and args.backend != "ray":
            raise ValueError("--address names a Ray cluster: use it with --backend ray")
        if args.log is not None:
            raise ValueError("--log: with --seeds each seed's logs go beside its zip")
        tasks, key, _ = training.check_request(
            args.task, args.algo, args.action_mode, args.steps, args.recipe
        )
        # Its folder holds the seeds' folders.
        training.check_policy_path(args.algo, args.out, tasks)
        check_eval_episodes(args.eval_episodes, tasks)
        plan = training.recipe(args.algo, key, args.recipe)
        _, _, note = training.check_collection(plan, tasks, args.n_envs, args.workers, args.steps)
        for seed in seeds:
            out = fanout.seed_out(args.out, seed)
            if out.parent.exists() and not out.parent.is_dir():
                raise ValueError(f"--out {args.out}: seed {seed}'s folder {out.parent} is a file")
            training.check_fresh(out)
            training.statistics_path(out, plan)
        if args.backend == "ray":
            check_ray(args.address)
    except ValueError as error:
        raise UsageError(str(error)) from None
    if note is not None:
        print(f"bbbench: {note}", file=sys.stderr)

    def done(run) -> None:
        args.written.append(f"{run.out.parent}/")
        print(f"seed {run.seed}: wrote {run.out.parent}/ ({run.seconds:.0f} s)", flush=True)

    def point(seed: int, steps: int, total: int, point: dict) -> None:
        print(
            f"seed {seed}: {steps:,} of {total:,} steps, {point['wall_time_s']:.0f} s: mean "
            f"return {point['mean']:.2f} on training seeds",
            flush=True,
        )

    try:
        runs = fanout.train_seeds(
            tasks,
            args.algo,
            args.out,
            seeds,
            backend=args.backend,
            address=args.address,
            on_done=done,
            on_point=point,
            action_mode=args.action_mode,
            steps=args.steps,
            n_envs=args.n_envs,
            final_episodes=args.eval_episodes,
            recipe_file=args.recipe,
            workers=args.workers,
        )
    except ConnectionError as error:
        raise UsageError(f"--address {args.address}: {error}") from None
    for run in runs:
        score = run.results["overall"]["normalized_score"]
        print(f"seed {run.seed}: {run.out}, mean normalized score {score:.3f}")
    return 0

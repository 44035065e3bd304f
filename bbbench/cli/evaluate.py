"""`bbbench eval`: score a policy on the suite's fixed evaluation seeds."""

from __future__ import annotations

import argparse
import json
import sys

from rich.console import Console
from rich.progress import MofNCompleteColumn, Progress

import bbbench
from bbbench.cli.common import (
    UsageError,
    add_contract_options,
    add_play_options,
    builtin_policies,
    builtins_in_either_mode,
    check_play_options,
    contract_options,
    results_table,
    say_normalization,
)
from bbbench.files import check_distinct_outputs, check_output_path, write_atomic
from bbbench.policies import PolicyError, load_policy
from bbbench.tasks.spec import SEED_SPLITS


def add_parser(commands) -> None:
    evaluate = commands.add_parser(
        "eval",
        help="score a policy on the suite's fixed evaluation seeds",
        description="Score a policy on the suite's fixed evaluation seeds: every task it fits, "
        "or those given with --task. POLICY is a stable-baselines3 .zip (read without "
        "unpickling anything), an ONNX model (.onnx, run by bbbench's own interpreter: "
        "bbbench export writes one) or a built-in: reference (the default, a PPO policy shipped "
        f"with bbbench), {', '.join(p for p in builtin_policies() if p != 'reference')}.",
    )
    evaluate.add_argument("policy", nargs="?", default="reference", metavar="POLICY")
    evaluate.add_argument(
        "--task", action="extend", nargs="+", metavar="ID", help="task ID(s); default: all it fits"
    )
    add_play_options(evaluate, episodes="the first N seeds of each task (default: all)")
    evaluate.add_argument(
        "--seeds",
        default="evaluation",
        metavar="SPLIT",
        help="which public seeds to play: evaluation (default: what the board scores) or "
        "validation (disjoint from them and from the training seeds: make choices there)",
    )
    add_contract_options(evaluate)
    evaluate.add_argument("--json", metavar="OUT", help="write the results document here")
    evaluate.add_argument(
        "--marl-eval",
        metavar="OUT",
        help="write the episodes in marl-eval's raw-data JSON (InstaDeep's id-marl-eval, "
        "BenchMARL's statistics), to put bbbench beside other MARL tasks",
    )
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
    evaluate.add_argument(
        "--action-mode",
        choices=("discrete", "continuous"),
        help=f"the action mode of a built-in that acts in either "
        f"({', '.join(builtins_in_either_mode())}; default discrete; random plays the "
        f"wheel-legged robot's tasks in continuous); a zip's is its own",
    )
    evaluate.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    policy, task_ids, per_task = _checked(args)
    result = _played(args, policy, task_ids, per_task)
    return _reported(args, policy, task_ids, result)


def _checked(args: argparse.Namespace):
    """The policy, the tasks and the episodes per task, every option checked before any
    episode is played."""
    from bbbench import evaluation  # lazy: bbbench.evaluation
    from bbbench.evaluation.backends import (  # lazy: bbbench.evaluation.backends
        check_ray,
        default_workers,
    )
    from bbbench.evaluation.video import check_video_path  # lazy: bbbench.evaluation.video

    check_play_options(args)
    if args.seeds not in SEED_SPLITS:
        raise UsageError(
            f"--seeds {args.seeds!r}: the public seeds are 'evaluation' (what the board "
            f"scores) or 'validation' (to make choices on)"
        )
    cores = default_workers()
    if args.workers is not None and args.workers > cores and not args.address:
        # evaluate() caps them; the command says so
        print(
            f"bbbench: --workers {args.workers} is more than the {cores} core(s) here: "
            f"using {cores}",
            file=sys.stderr,
        )
    try:  # everything the run will need, before any episode is played
        check_distinct_outputs(
            {"--json": args.json, "--video": args.video, "--marl-eval": args.marl_eval}
        )
        for flag, path in (("--json", args.json), ("--marl-eval", args.marl_eval)):
            if path is not None:
                check_output_path(path, flag)
        if args.video is not None:
            check_video_path(args.video)
        if args.backend == "ray":
            check_ray(args.address)
        policy = load_policy(
            args.policy,
            vecnormalize=args.vecnormalize,
            action_mode=args.action_mode,
            **contract_options(args),
        )
        task_ids = evaluation.select_tasks(policy, args.task)
    except (PolicyError, ValueError) as error:
        raise UsageError(str(error)) from None
    say_normalization(policy)
    most = min(len(bbbench.spec(task_id).seeds(args.seeds)) for task_id in task_ids)
    if args.episodes is not None and args.episodes > most:
        raise UsageError(
            f"--episodes {args.episodes}: the tasks have {most} {args.seeds} seeds each"
        )
    return policy, task_ids, args.episodes or most


def _played(args: argparse.Namespace, policy, task_ids: list[str], per_task: int):
    """`evaluate`, with a progress bar on a terminal."""
    from bbbench import evaluation  # lazy: bbbench.evaluation

    console = Console(stderr=True)
    with Progress(
        *Progress.get_default_columns(),
        MofNCompleteColumn(),
        console=console,
        transient=True,
        disable=not console.is_terminal,
    ) as progress:
        bar = progress.add_task(
            f"{policy.name}: {len(task_ids)} task(s)", total=per_task * len(task_ids)
        )
        try:
            return evaluation.evaluate(
                policy,
                task_ids,
                episodes=args.episodes,
                workers=args.workers,
                backend=args.backend,
                address=args.address,
                stochastic=args.stochastic,
                on_result=lambda count, played: progress.advance(bar, count),
                split=args.seeds,
            )
        except PolicyError as error:  # its network cannot be built for a task's spaces
            raise UsageError(str(error)) from None
        except ConnectionError as error:  # Ray answered on the port, then failed
            raise UsageError(f"--address {args.address}: {error}") from None


def _reported(args: argparse.Namespace, policy, task_ids: list[str], result) -> int:
    """The table, the files asked for, and the exit code (1 if episodes are missing)."""
    from bbbench import evaluation  # lazy: bbbench.evaluation
    from bbbench.evaluation.video import record_episode  # lazy: bbbench.evaluation.video

    document = result.document
    out = Console()
    if not out.is_terminal:  # a pipe or a file: wide enough that nothing is cut
        out = Console(width=120)
    out.print(results_table(document))
    if args.json is not None:
        write_atomic(args.json, evaluation.dumps(document).encode())
        args.written.append(args.json)
        print(f"wrote {args.json}")
    if args.marl_eval is not None:
        from bbbench.evaluation.marl_eval import marl_eval_document  # lazy: bbbench.evaluation

        steps = getattr(policy, "training_steps", None)
        data = marl_eval_document(document, steps, getattr(policy, "training_seed", None))
        write_atomic(args.marl_eval, (json.dumps(data, indent=1) + "\n").encode())
        args.written.append(args.marl_eval)
        print(f"wrote {args.marl_eval} (marl-eval's raw data)")
    if args.video is not None:
        task_id = task_ids[0]
        seed = bbbench.spec(task_id).seeds(args.seeds)[0]
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

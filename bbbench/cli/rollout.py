"""`bbbench rollout`: a policy on a task's episodes, episode by episode."""

from __future__ import annotations

import argparse
import statistics

import bbbench
from bbbench.cli.common import UsageError, builtin_policies, check_seed, say_normalization
from bbbench.policies import PolicyError, load_policy


def add_parser(commands) -> None:
    rollout = commands.add_parser(
        "rollout", help="run a policy on a task's episodes and print a summary"
    )
    rollout.add_argument("--task", default="bbbench/FlatBalance-v1", help="task ID")
    rollout.add_argument(
        "--policy",
        default="pd",
        metavar="POLICY",
        help=f"a built-in ({', '.join(builtin_policies())}) or a stable-baselines3 .zip "
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
    rollout.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    from bbbench.evaluation.episodes import action_generator  # lazy: only this command needs it
    from bbbench.evaluation.play import Lockstep  # lazy: only this command needs it

    try:
        spec = bbbench.spec(args.task)
    except ValueError as error:
        raise UsageError(str(error)) from None
    if args.episodes < 1:
        raise UsageError(f"--episodes must be at least 1, got {args.episodes}")
    check_seed(args.seed)
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
        reason = policy.mismatch(spec.id)
        if reason:
            raise PolicyError(
                f"{policy.name} ({policy.spaces_text()}) cannot play {spec.id}: {reason}"
            )
        actor = policy.actor(spec.id)
    except PolicyError as error:
        raise UsageError(str(error)) from None
    say_normalization(policy)
    env = bbbench.make(spec.id, action_mode=policy.action_mode, **policy.env_options())
    acting = "random actions" if policy.random_actions else "deterministic"
    print(
        f"{spec.id}: {args.episodes} episode(s) of the {policy.name!r} policy ({acting}), "
        f"seeds {args.seed}..{args.seed + args.episodes - 1}"
    )
    print(f"{'seed':>8}  {'steps':>5}  {'return':>8}  ended by")
    returns, lengths = [], []
    for seed in range(args.seed, args.seed + args.episodes):
        rngs = [action_generator(seed)] if policy.random_actions else None
        (result,) = Lockstep([env], actor, [seed], spec.max_episode_steps, rngs).play()
        ended = result.failure or ("fall" if result.falls else "time limit")
        returns.append(result.episode_return)
        lengths.append(result.length)
        print(f"{seed:>8}  {result.length:>5}  {result.episode_return:>8.2f}  {ended}")
    env.close()
    print(
        f"mean return {statistics.fmean(returns):.2f} of at most {spec.max_return:g}; "
        f"mean length {statistics.fmean(lengths):.0f} of {spec.max_episode_steps} steps; "
        f"{sum(n == spec.max_episode_steps for n in lengths)}/{len(lengths)} "
        f"episodes reached the time limit"
    )

"""`bbbench rollout`: a policy on a task's episodes, episode by episode."""

from __future__ import annotations

import argparse
import statistics

import bbbench
from bbbench.cli.common import (
    UsageError,
    add_contract_options,
    builtin_policies,
    check_seed,
    contract_options,
    say_normalization,
)
from bbbench.policies import PolicyError, load_policy
from bbbench.policies.policy import fitting_tasks
from bbbench.portable import total

DEFAULT_TASK = "bbbench/FlatBalance-v1"


def add_parser(commands) -> None:
    rollout = commands.add_parser(
        "rollout", help="run a policy on a task's episodes and print a summary"
    )
    rollout.add_argument(
        "--task",
        help=f"task ID (default {DEFAULT_TASK} if the policy plays it, else the first task "
        f"of the suite it plays)",
    )
    rollout.add_argument(
        "--policy",
        default="pd",
        metavar="POLICY",
        help=f"a built-in ({', '.join(builtin_policies())}), a stable-baselines3 .zip or an "
        f"ONNX model (default pd); on a multi-bot task every bot plays it",
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
    rollout.add_argument(
        "--video",
        metavar="OUT",
        help="write the first episode (.gif or .mp4); on a multi-bot task, the whole group",
    )
    add_contract_options(rollout)
    rollout.set_defaults(run=run)


def default_task(policy) -> str:
    """The task a rollout plays when none is named: FlatBalance if the policy plays it,
    else the first task of the suite (latest versions) it plays."""
    fits = fitting_tasks(policy)
    if not fits:
        raise PolicyError(f"{policy.name} ({policy.spaces_text()}) plays no task of the suite")
    return DEFAULT_TASK if DEFAULT_TASK in fits else fits[0]


def run(args: argparse.Namespace) -> None:
    from bbbench.evaluation.video import check_video_path  # lazy: bbbench.evaluation.video

    try:
        if args.task is not None:
            bbbench.spec(args.task)
    except ValueError as error:
        raise UsageError(str(error)) from None
    if args.episodes < 1:
        raise UsageError(f"--episodes must be at least 1, got {args.episodes}")
    check_seed(args.seed)
    try:
        if args.video is not None:
            check_video_path(args.video)
        policy = load_policy(
            args.policy,
            vecnormalize=args.vecnormalize,
            action_mode=args.action_mode,
            **contract_options(args),
        )
        spec = bbbench.spec(args.task or default_task(policy))
        reason = policy.mismatch(spec.id)
        if reason:
            raise PolicyError(
                f"{policy.name} ({policy.spaces_text()}) cannot play {spec.id}: {reason}"
            )
        actor = policy.actor(spec.id)
    except (PolicyError, ValueError) as error:
        raise UsageError(str(error)) from None
    say_normalization(policy)
    acting = "random actions" if policy.random_actions else "deterministic"
    shared = f", shared by {spec.group.n_bots} bots" if spec.multi_agent else ""
    print(
        f"{spec.id}: {args.episodes} episode(s) of the {policy.name!r} policy ({acting}{shared}), "
        f"seeds {args.seed}..{args.seed + args.episodes - 1}"
    )
    seeds = range(args.seed, args.seed + args.episodes)
    team = spec.multi_agent and spec.scenario_class.team
    play = _play_group if spec.multi_agent else _play_alone
    returns, lengths = play(spec, policy, actor, seeds)
    per_bot = " (the team's)" if team else " per bot" if spec.multi_agent else ""
    print(
        f"mean return{per_bot} {statistics.fmean(returns):.2f} of at most {spec.max_return:g}; "
        f"mean length {statistics.fmean(lengths):.0f} of {spec.max_episode_steps} steps; "
        f"{total(n == spec.max_episode_steps for n in lengths)}/{len(lengths)} "
        f"episodes reached the time limit"
    )
    if args.video is not None:
        from bbbench.evaluation.video import record_episode  # lazy: imageio, for --video only

        frames = record_episode(policy, spec.id, args.seed, args.video)
        args.written.append(args.video)
        print(f"wrote {args.video}: {spec.id}, episode seed {args.seed}, {frames} frames")


def _play_alone(spec, policy, actor, seeds) -> tuple[list[float], list[int]]:
    """Single-bot episodes, one row each: steps, return, what ended it."""
    from bbbench.evaluation.episodes import action_generator  # lazy: bbbench.evaluation.episodes
    from bbbench.evaluation.play import Lockstep  # lazy: bbbench.evaluation.play

    env = bbbench.make(spec.id, action_mode=policy.action_mode, **policy.env_options())
    print(f"{'seed':>8}  {'steps':>5}  {'return':>8}  ended by")
    returns, lengths = [], []
    for seed in seeds:
        rngs = [action_generator(seed)] if policy.random_actions else None
        (result,) = Lockstep([env], actor, [seed], rngs=rngs).play()
        ended = result.failure or ("fall" if result.falls else "time limit")
        returns.append(result.episode_return)
        lengths.append(result.length)
        print(f"{seed:>8}  {result.length:>5}  {result.episode_return:>8.2f}  {ended}")
    env.close()
    return returns, lengths


def _play_group(spec, policy, actor, seeds) -> tuple[list[float], list[int]]:
    """Multi-bot episodes, the policy shared by every bot, one row each: the mean return
    per bot and the falls, then each bot's return and the step it fell at; on a team task
    the team's return (every bot's), its mean velocity error, and what ended it (the bots
    that fell, a broken tether, or the time limit)."""
    from bbbench.evaluation.episodes import action_generator  # lazy: bbbench.evaluation.episodes
    from bbbench.evaluation.play import MultiEpisode  # lazy: bbbench.evaluation.play

    env = bbbench.make_parallel(spec.id, action_mode=policy.action_mode)
    team = spec.scenario_class.team
    head = "error m/s  ended by" if team else "falls  each bot: return (fell at step)"
    print(f"{'seed':>8}  {'steps':>5}  {'return':>8}  {head}")
    returns, lengths = [], []
    for seed in seeds:
        rng = action_generator(seed) if policy.random_actions else None
        episode = MultiEpisode(env, actor, seed, rng)
        result = episode.play()
        returns.append(result.episode_return)
        lengths.append(result.length)
        row = _team_row(env, result) if team else _bots_row(env, episode, result)
        print(f"{seed:>8}  {result.length:>5}  {result.episode_return:>8.2f}  {row}")
    env.close()
    return returns, lengths


def _bots_row(env, episode, result) -> str:
    each = "  ".join(
        f"{agent} {episode.returns[agent]:.2f}"
        + (f" ({episode.fell[agent]})" if agent in episode.fell else "")
        for agent in env.possible_agents
    )
    failure = f"  {result.failure}" if result.failure else ""
    return f"{f'{result.falls}/{len(env.possible_agents)}':>5}  {each}{failure}"


def _team_row(env, result) -> str:
    return f"{result.metrics['velocity_error']:>9.3f}  {result.failure or result.cause}"

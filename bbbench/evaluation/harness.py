"""`evaluate`: a policy's episodes on the tasks' fixed evaluation seeds, run by the chosen
backend (this process, worker processes, or Ray), as a results document."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

from bbbench.evaluation.backends import BACKENDS, default_workers, run_local, run_ray
from bbbench.evaluation.episodes import LockstepPlayer, Players
from bbbench.evaluation.play import PlayedEpisode
from bbbench.evaluation.results import document
from bbbench.policies.errors import PolicyError
from bbbench.policies.policy import Policy, fitting_tasks
from bbbench.portable import total
from bbbench.tasks.spec import TaskSpec
from bbbench.tasks.suite import list_tasks, spec

LOCKSTEP = 8  # single-bot episodes a worker plays side by side


@dataclasses.dataclass(frozen=True)
class Evaluation:
    """What `evaluate` returns: the results document, and the episodes it lacks."""

    document: dict[str, Any]
    missing: list[tuple[str, int]]  # (task ID, seed) of episodes whose worker died twice
    steps: int  # environment steps played (bot-steps on multi-bot tasks count once)


def select_tasks(policy: Policy, requested: Sequence[str] | None = None) -> list[str]:
    """The tasks to evaluate: those requested (each must fit the policy), else every task
    of the suite the policy fits (its latest version; an older one when requested).
    `ValueError` for an unknown ID; `PolicyError` otherwise."""
    if requested:
        task_ids = list(dict.fromkeys(spec(task_id).id for task_id in requested))
        check_fits(policy, task_ids)
        return task_ids
    task_ids = fitting_tasks(policy)
    if not task_ids:
        wants = "; ".join(policy.mismatch(task_id) or "" for task_id in list_tasks(latest=True))
        raise PolicyError(
            f"{policy.name} ({policy.spaces_text()}) fits no task of the suite: {wants}"
        )
    return task_ids


def check_fits(policy: Policy, task_ids: Sequence[str]) -> None:
    """`PolicyError` naming each of `task_ids` the policy cannot play, and why."""
    unfit = [reason for task_id in dict.fromkeys(task_ids) if (reason := policy.mismatch(task_id))]
    if unfit:
        raise PolicyError(f"{policy.name} ({policy.spaces_text()}) cannot play: {'; '.join(unfit)}")


def evaluate(
    policy: Policy,
    task_ids: Sequence[str],
    episodes: int | None = None,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
    stochastic: bool = False,
    on_result: Callable[[int, list[PlayedEpisode] | None], None] | None = None,
    split: str = "evaluation",
) -> Evaluation:
    """Play the first `episodes` eval seeds (default: all) of each task, each episode
    seeded with `reset(seed=s)`, on `workers` processes (default: every core) of the
    local machine or of Ray; aggregate them into the results document. `split=
    "validation"` plays the tasks' validation seeds instead (`TaskSpec.seeds`): the ones
    to make choices on.

    Single-bot episodes run in groups of `LOCKSTEP` consecutive seeds, side by
    side, so the policy's network runs once per step for the group.
    `on_result(n, results)` is called as each group of n episodes ends (results
    None if its worker died twice).
    """
    # A policy that observes the ground ahead plays every task with the height scan on.
    tasks = [spec(task_id).with_height_scan(policy.height_scan) for task_id in task_ids]
    seeds = [list(task.seeds(split)[:episodes]) for task in tasks]
    played = play_tasks(
        policy, tasks, episodes, workers, backend, address, stochastic, on_result, seeds
    )
    results = dict(zip(task_ids, played.episodes, strict=True))
    document = results_document(policy, results, stochastic, split)
    return Evaluation(document, played.missing, played.steps)


@dataclasses.dataclass(frozen=True)
class Played:
    """What `play_tasks` returns: per task, its episodes in seed order (None: missing)."""

    episodes: list[list[PlayedEpisode | None]]
    missing: list[tuple[str, int]]  # (task ID, seed) of episodes whose worker died twice
    steps: int  # environment steps played (bot-steps on multi-bot tasks count once)


def play_tasks(
    policy: Policy,
    tasks: Sequence[TaskSpec],
    episodes: int | None = None,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
    stochastic: bool = False,
    on_result: Callable[[int, list[PlayedEpisode] | None], None] | None = None,
    seeds: Sequence[Sequence[int]] | None = None,
) -> Played:
    """The episodes of `evaluate`, for task specs: the suite's, or variants of them (a
    perturbation, another difficulty or number of bots: `bbbench sweep`), all on one pool
    of workers. Each task plays its first `episodes` eval seeds, or `seeds[i]` (any of
    its public seeds, in any order: an episode depends on its seed alone). `PolicyError`
    for a task the policy cannot play, before anything is played."""
    if episodes is not None and episodes < 1:
        raise ValueError(f"episodes must be at least 1, got {episodes}")
    check_fits(policy, [task.id for task in tasks])
    if seeds is None:
        seeds = [list(task.eval_seeds[:episodes]) for task in tasks]
    # Fixed groups of consecutive seeds, whatever the workers: the same groups, the same bytes.
    jobs = [
        (task, tuple(task_seeds[start : start + LOCKSTEP]))
        for task, task_seeds in zip(tasks, seeds, strict=True)
        for start in range(0, len(task_seeds), LOCKSTEP)
    ]
    runner = _player(policy, dict.fromkeys(task.id for task in tasks), stochastic)
    done = _run(runner, jobs, workers, backend, address, on_result)
    by_job = iter(done)
    results: list[list[PlayedEpisode | None]] = []
    for task_seeds in seeds:
        episodes_of_task: list[PlayedEpisode | None] = []
        for start in range(0, len(task_seeds), LOCKSTEP):
            group = next(by_job)
            size = len(task_seeds[start : start + LOCKSTEP])
            episodes_of_task += [None] * size if group is None else group
        results.append(episodes_of_task)
    missing = [
        (task.id, seed)
        for task, task_seeds, played in zip(tasks, seeds, results, strict=True)
        for seed, episode in zip(task_seeds, played, strict=True)
        if episode is None
    ]
    steps = total(episode.length for played in results for episode in played if episode is not None)
    return Played(results, missing, steps)


def results_document(
    policy: Policy,
    results: Mapping[str, Sequence[PlayedEpisode | None]],
    stochastic: bool = False,
    split: str = "evaluation",
) -> dict[str, Any]:
    """The results document of `policy`'s episodes: `results[task_id]` holds the episodes
    on the task's first seeds of `split` (eval seeds by default), in order (None for one
    that is missing)."""
    tasks = [spec(task_id).with_height_scan(policy.height_scan) for task_id in results]
    played = list(results.values())
    seeds = [
        list(task.seeds(split)[: len(episodes)])
        for task, episodes in zip(tasks, played, strict=True)
    ]
    deterministic = not (stochastic or policy.random_actions)
    return document(policy.record(), tasks, seeds, played, deterministic, split)


def play_draws(
    draws: Sequence[tuple[Policy, TaskSpec, int]],
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
    on_result: Callable[[int, list[PlayedEpisode] | None], None] | None = None,
) -> list[PlayedEpisode | None]:
    """One episode per (policy, spec, seed) draw, in order (None: lost), deterministic
    actions, all on one pool of workers: what a spot-check replays.

    A policy's single-bot draws of one task ID (whatever their perturbations) run side
    by side in groups of `LOCKSTEP`, so its network runs once per step for the group.
    The groups are cut from the specs in the order they first appear, and the jobs are
    sent group by group, policy after policy: policies that draw the same specs play them
    one after another in the same worlds, built once (a world takes some 30 ms to build,
    half of a short episode). An episode depends on its spec and seed alone, so neither
    the groups nor the worlds change a result."""
    policies: list[Policy] = []
    index: dict[int, int] = {}  # id(policy): its place in `policies`
    for policy, _, _ in draws:
        if id(policy) not in index:
            index[id(policy)] = len(policies)
            policies.append(policy)
    first = {task: n for n, task in enumerate(dict.fromkeys(task for _, task, _ in draws))}
    groups: dict[tuple[int, str, bool], list[int]] = {}  # (policy, task ID, multi): draws
    for i, (policy, task, _) in enumerate(draws):
        groups.setdefault((index[id(policy)], task.id, task.multi_agent), []).append(i)
    jobs: list[tuple[Any, list[int], Any, tuple[int, ...]]] = []  # (order, draws, task, seeds)
    for (k, _, multi), indices in groups.items():
        indices.sort(key=lambda i: first[draws[i][1]])
        size = 1 if multi else LOCKSTEP
        for start in range(0, len(indices), size):
            chunk = indices[start : start + size]
            tasks = tuple(draws[i][1] for i in chunk)
            order = (tuple(first[task] for task in tasks), k)
            jobs.append(
                (order, chunk, (k, tasks[0] if multi else tasks), tuple(draws[i][2] for i in chunk))
            )
    jobs.sort(key=lambda job: job[0])
    task_ids: list[dict[str, None]] = [{} for _ in policies]  # per policy, the IDs it plays
    for k, task_id, _ in groups:
        task_ids[k][task_id] = None
    runner = Players(tuple(map(_player, policies, task_ids)))
    plain = [(task, seeds) for _, _, task, seeds in jobs]
    done = _run(runner, plain, workers, backend, address, on_result)
    results: list[PlayedEpisode | None] = [None] * len(draws)
    for (_, indices, _, _), played in zip(jobs, done, strict=True):
        for position, i in enumerate(indices):
            results[i] = None if played is None else played[position]
    return results


def _player(policy: Policy, task_ids: Iterable[str], stochastic: bool = False) -> LockstepPlayer:
    """The runner of `policy`'s episodes on `task_ids` (deterministic actions unless
    `stochastic`)."""
    return LockstepPlayer(
        actors={task_id: policy.acting(task_id, stochastic) for task_id in task_ids},
        action_mode=policy.action_mode,
        sampled=stochastic or policy.random_actions,
        height_scan=policy.height_scan,
    )


def _run(
    runner: LockstepPlayer | Players,
    jobs: Sequence[tuple[Any, tuple[int, ...]]],
    workers: int | None,
    backend: str,
    address: str | None,
    on_result: Callable[[int, list[PlayedEpisode] | None], None] | None,
) -> list[list[PlayedEpisode] | None]:
    """Play `jobs` (what the runner plays, and the seeds) on the backend's workers
    (default: every core); each job's episodes, or None if its worker died twice.
    `on_result(n, episodes)` as each job of n episodes ends."""
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    workers = default_workers() if workers is None else workers
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    if address is None:  # this machine: more processes than cores only cost memory
        workers = min(workers, default_workers())

    def report(index: int, played: list[PlayedEpisode] | None) -> None:
        if on_result is not None:
            on_result(len(jobs[index][1]), played)

    if backend == "ray":
        return run_ray(runner, jobs, workers, report, address=address)
    return run_local(runner, jobs, workers, report)

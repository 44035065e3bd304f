"""Evaluation benchmark: `bbbench eval` against the bare env, and 2 workers against 1.

    python benchmarks/bench_eval.py [--episodes 100] [--rounds 3]

1. The network: the reference policy's MLP per call, in numpy (`MlpActor`) and in
   torch (stable-baselines3's own module and `predict`), for one observation and
   for batches of 8 and 16.
2. Throughput, one worker: the whole command, `bbbench eval --episodes N
   --workers 1` (the reference policy on every single-bot task: with N = 100,
   750,000 steps), timed from start to exit, in environment steps per second;
   against the bare env, `bbbench.make(task)`, replaying the very same
   episodes' actions (recorded beforehand), in steps per second.
3. Two workers against one: the same command with `--workers 2`.
4. The same two without the command's start-up: `evaluate(policy, tasks,
   workers=N)` in this process, the policy already loaded (torch imported), timed
   from the call to its return (workers' start, episodes, statistics).
5. The machine's own ceiling for two workers: the bare env replaying every
   episode in one forked process, against two forked processes side by side
   replaying half each; wall time from the first fork to the last exit.
6. The command's fixed cost F: `bbbench eval --episodes 1 --task
   bbbench/FlatBalance-v0 --workers 1` (Python, the imports, torch, the zip, a
   worker, one world, the statistics, the exit), less its one episode's steps at
   the one-worker command's rate; and Amdahl's estimate for two workers from it:
   the one-worker time T1 with everything but F spread at the machine's own
   two-process ceiling c (5.), T1 / (F + (T1 - F) / c). It is an estimate, not a
   bound: its parts are measured minutes apart, in different phases of the
   machine.

The runs alternate, round by round, so they share the machine's slow and fast
phases; each ratio is computed within a round.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import bbbench
from bbbench.evaluation import evaluate
from bbbench.evaluation.results import read
from bbbench.policies import load_policy
from bbbench.policies.policy import act_once
from bbbench.policies.registry import REFERENCE_POLICY
from bbbench.policies.sb3.policy import SB3ZipPolicy


def time_per_call(function, argument, calls: int) -> float:
    """Microseconds per call, best of 3."""
    best = float("inf")
    for _ in range(3):
        began = time.perf_counter()
        for _ in range(calls):
            function(argument)
        best = min(best, time.perf_counter() - began)
    return best / calls * 1e6


def network_costs() -> None:
    task = "bbbench/FlatBalance-v0"
    numpy_actor = load_policy("reference").actor(task)
    torch_policy = SB3ZipPolicy(REFERENCE_POLICY, backend="torch").actor(task).policy
    import torch

    rng = np.random.default_rng(0)
    print("reference MLP (5 -> 64 -> 64 -> 9, tanh), microseconds per call:")
    print(f"{'batch':>6}  {'numpy':>8}  {'torch module':>12}  {'torch predict':>13}")
    for batch in (1, 8, 16):
        observations = rng.normal(size=(batch, 5)).astype(np.float32)
        tensor = torch.from_numpy(observations)

        def module(x, policy=torch_policy):
            with torch.no_grad():
                return policy.action_net(policy.mlp_extractor.forward_actor(x))

        numpy_us = time_per_call(numpy_actor, observations, 20_000)
        module_us = time_per_call(module, tensor, 5_000)
        predict_us = time_per_call(
            lambda x: torch_policy.predict(x, deterministic=True), observations, 5_000
        )
        print(f"{batch:>6}  {numpy_us:>8.1f}  {module_us:>12.1f}  {predict_us:>13.1f}")
    one = rng.normal(size=5).astype(np.float32)
    single = time_per_call(lambda x: act_once(numpy_actor, x), one, 20_000)
    print(f"one observation through act_once (numpy): {single:.1f} us")


def record_actions(episodes: int) -> dict[str, list[tuple[int, list]]]:
    """The reference policy's actions on each single-bot task's first eval seeds (played
    alone; the evaluation's lockstep groups play the same episodes, but for near-ties in
    the network's last bits)."""
    policy = load_policy("reference")
    recorded: dict[str, list[tuple[int, list]]] = {}
    for task_id in bbbench.list_tasks(multi_agent=False):
        actor, env = policy.actor(task_id), bbbench.make(task_id)
        recorded[task_id] = []
        for seed in bbbench.spec(task_id).eval_seeds[:episodes]:
            observation, _ = env.reset(seed=seed)
            actions, done = [], False
            while not done:
                actions.append(act_once(actor, observation))
                observation, _, terminated, truncated, _ = env.step(actions[-1])
                done = terminated or truncated
            recorded[task_id].append((seed, actions))
        env.close()
    return recorded


def bare_env_rate(recorded: dict[str, list[tuple[int, list]]]) -> tuple[float, int]:
    """Steps per second of `bbbench.make(task)` replaying the recorded episodes."""
    steps, elapsed = 0, 0.0
    for task_id, episodes in recorded.items():
        env = bbbench.make(task_id)
        for seed, actions in episodes:
            began = time.perf_counter()
            env.reset(seed=seed)
            step = env.step
            for action in actions:
                step(action)
            elapsed += time.perf_counter() - began
            steps += len(actions)
        env.close()
    return steps / elapsed, steps


def bare_env_processes_rate(recorded: dict[str, list[tuple[int, list]]], processes: int) -> float:
    """Steps per second of `processes` forked processes replaying the recorded episodes
    (each every `processes`-th episode of each task), from the first fork to the last exit."""
    context = multiprocessing.get_context("fork")
    shares = [
        {task_id: episodes[k::processes] for task_id, episodes in recorded.items()}
        for k in range(processes)
    ]
    began = time.perf_counter()
    running = [context.Process(target=bare_env_rate, args=(share,)) for share in shares]
    for process in running:
        process.start()
    for process in running:
        process.join()
    elapsed = time.perf_counter() - began
    return sum(len(actions) for eps in recorded.values() for _, actions in eps) / elapsed


def command_seconds(*arguments: str) -> float:
    """Wall time of `python -m bbbench eval ARGUMENTS`, from start to exit."""
    began = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "bbbench", "eval", *arguments],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    return time.perf_counter() - began


def command_rate(episodes: int, workers: int, out: Path) -> tuple[float, int]:
    """Environment steps per second of the whole `bbbench eval` command."""
    elapsed = command_seconds(
        "--episodes", str(episodes), "--workers", str(workers), "--json", str(out)
    )
    document = read(out)
    steps = sum(e["length"] for task in document["tasks"] for e in task["episodes"])
    return steps / elapsed, steps


def evaluate_rate(policy, episodes: int, workers: int) -> float:
    """Environment steps per second of `evaluate()`, the policy already loaded."""
    tasks = bbbench.list_tasks(multi_agent=False)
    began = time.perf_counter()
    evaluation = evaluate(policy, tasks, episodes=episodes, workers=workers)
    return evaluation.steps / (time.perf_counter() - began)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100, help="eval seeds per task")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    print(f"bbbench {bbbench.__version__}, {os.cpu_count()} cores, Python {sys.version.split()[0]}")
    network_costs()
    recorded = record_actions(args.episodes)
    print(f"\nreference policy on {len(recorded)} single-bot tasks x {args.episodes} eval seeds")
    policy = load_policy("reference")
    one_vs_bare, two_vs_one, evaluate_two_vs_one, bare_two_vs_one, estimates = [], [], [], [], []
    with tempfile.TemporaryDirectory() as folder:
        for round_ in range(1, args.rounds + 1):
            bare, bare_steps = bare_env_rate(recorded)
            one, steps = command_rate(args.episodes, 1, Path(folder) / "one.json")
            two, _ = command_rate(args.episodes, 2, Path(folder) / "two.json")
            one_json, two_json = Path(folder) / "one.json", Path(folder) / "two.json"
            if one_json.read_bytes() != two_json.read_bytes():
                raise SystemExit("1 and 2 workers wrote different results")
            one_in, two_in = (evaluate_rate(policy, args.episodes, n) for n in (1, 2))
            bare_one, bare_two = (bare_env_processes_rate(recorded, n) for n in (1, 2))
            bare_two_vs_one.append(bare_two / bare_one)
            fixed_json = Path(folder) / "fixed.json"
            fixed = command_seconds(
                "--episodes", "1", "--task", "bbbench/FlatBalance-v0", "--workers", "1",
                "--json", str(fixed_json),
            )  # fmt: skip
            # less its one episode's steps, at the one-worker command's own rate
            fixed -= read(fixed_json)["tasks"][0]["episodes"][0]["length"] / one
            one_seconds, ceiling = steps / one, bare_two / bare_one
            estimates.append(one_seconds / (fixed + (one_seconds - fixed) / ceiling))
            one_vs_bare.append(one / bare)
            two_vs_one.append(two / one)
            evaluate_two_vs_one.append(two_in / one_in)
            print(
                f"round {round_}: bare env {bare:,.0f} steps/s ({bare_steps:,} steps); "
                f"eval, 1 worker {one:,.0f} steps/s ({steps:,} steps) = {one / bare:.3f}x bare; "
                f"2 workers {two:,.0f} steps/s = {two / one:.2f}x 1 worker; "
                f"evaluate(), 1 worker {one_in:,.0f} steps/s, 2 workers {two_in:,.0f} steps/s "
                f"= {two_in / one_in:.2f}x; bare env in 2 processes / 1 {ceiling:.2f}x; "
                f"the command's fixed cost {fixed:.2f} s of the 1-worker {one_seconds:.2f} s: "
                f"Amdahl's estimate for 2 workers {estimates[-1]:.2f}x"
            )
    print(
        f"\nmedian: 1 worker / bare env {statistics.median(one_vs_bare):.3f} (target >= 0.7); "
        f"2 workers / 1 worker {statistics.median(two_vs_one):.2f} (target >= 1.8); "
        f"without start-up, 2 workers / 1 worker {statistics.median(evaluate_two_vs_one):.2f}; "
        f"bare env, 2 processes / 1 {statistics.median(bare_two_vs_one):.2f}; "
        f"Amdahl's estimate from the fixed cost and that ceiling {statistics.median(estimates):.2f}"
    )


if __name__ == "__main__":
    main()

"""A/B benchmark: this checkout against another revision of bbbench, on the hot paths a
change of the env layer could slow.

    git worktree add /tmp/bbbench-base <revision>     # the revision to compare against
    python benchmarks/bench_ab.py --base /tmp/bbbench-base [--rounds 7]

Three workloads, each run in a fresh process per measurement with the checkout's
`bbbench` first on the path, the two checkouts taking turns (A B A B ...) so they
share the machine's slow and fast phases; each process times only its own loop
(imports and world building excluded), and the ratio of each round's pair is
reported (median, min, max over the rounds; above 1 means this checkout is slower):

- `flat`: FlatBalance-v1's `BalanceEnv.step` (no wrappers), PD's actions, resets
  excluded: seconds per step;
- `multi`: MultiBalance-v1 with 8 bots, PD's actions on every live bot, resets
  excluded: seconds per bot-step;
- `eval`: `evaluate(pd, ["bbbench/VelocityTracking-v1"], episodes=20, workers=1)`,
  seconds per env step (the harness's lockstep loop, results document included);
- with `--workloads ... steer swap`: SteerTracking-v0's step with `steer`'s actions, and
  Swap-v0's with 4 bots and `steer-avoid`'s (the steering robot).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent
WORKLOADS = ("flat", "multi", "eval")
EXTRA = ("steer", "swap")  # the steering robot's single-bot and multi-bot steps


def flat(steps: int, task_id: str = "bbbench/FlatBalance-v1", controller: str = "pd") -> float:
    import bbbench
    from bbbench.envs.balance import BalanceEnv
    from bbbench.policies import load_policy

    env = BalanceEnv(bbbench.spec(task_id))
    act = load_policy(controller).actor(task_id)
    seeds = iter(bbbench.spec(task_id).eval_seeds * 1000)
    observation, _ = env.reset(seed=next(seeds))
    spent, done = 0.0, 0
    while done < steps:
        (action,) = act(observation[None], None)
        began = time.perf_counter()
        observation, _, terminated, _, _ = env.step(action)
        spent += time.perf_counter() - began
        done += 1
        if terminated or env.scene.steps >= 1500:
            observation, _ = env.reset(seed=next(seeds))
    return spent / steps


def steer(steps: int) -> float:
    """SteerTracking-v0's `BalanceEnv.step`, the steering controller's actions."""
    return flat(steps, "bbbench/SteerTracking-v0", "steer")


def multi(
    bot_steps: int, task_id: str = "bbbench/MultiBalance-v1", controller: str = "pd", bots: int = 8
) -> float:
    import numpy as np

    import bbbench
    from bbbench.policies import load_policy

    env = bbbench.make_parallel(task_id, n_bots=bots)
    act = load_policy(controller).actor(task_id)
    seeds = iter(bbbench.spec(task_id).eval_seeds * 1000)
    observations, _ = env.reset(seed=next(seeds))
    spent, done = 0.0, 0
    while done < bot_steps:
        agents = env.agents
        batch = np.stack([observations[agent] for agent in agents])
        actions = dict(zip(agents, act(batch, None), strict=True))
        began = time.perf_counter()
        observations, *_ = env.step(actions)
        spent += time.perf_counter() - began
        done += len(agents)
        if not env.agents:
            observations, _ = env.reset(seed=next(seeds))
    return spent / done


def swap(bot_steps: int) -> float:
    """Swap-v0 with 4 bots (the steering robot's multi-bot step), steer-avoid's actions."""
    return multi(bot_steps, "bbbench/Swap-v0", "steer-avoid", 4)


def evaluation(episodes: int) -> float:
    from bbbench.evaluation import evaluate
    from bbbench.policies import load_policy

    policy = load_policy("pd")
    began = time.perf_counter()
    played = evaluate(policy, ["bbbench/VelocityTracking-v1"], episodes=episodes, workers=1)
    return (time.perf_counter() - began) / played.steps


def worker(workload: str, size: int) -> None:
    import bbbench

    workloads = {"flat": flat, "multi": multi, "eval": evaluation, "steer": steer, "swap": swap}
    seconds = workloads[workload](size)
    print(json.dumps({"seconds": seconds, "bbbench": str(Path(bbbench.__file__).parent)}))


def measure(tree: Path, workload: str, size: int) -> float:
    environment = {**os.environ, "PYTHONPATH": str(tree)}
    command = [sys.executable, str(Path(__file__).resolve()), "--worker", workload, str(size)]
    out = subprocess.run(command, env=environment, capture_output=True, text=True, check=True)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    if Path(result["bbbench"]) != tree / "bbbench":
        raise SystemExit(f"{tree}: the worker imported bbbench from {result['bbbench']}")
    return result["seconds"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", type=Path, help="a checkout of the revision to compare with")
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--flat-steps", type=int, default=30_000)
    parser.add_argument("--multi-bot-steps", type=int, default=60_000)
    parser.add_argument("--eval-episodes", type=int, default=20)
    parser.add_argument(
        "--workloads", nargs="*", choices=WORKLOADS + EXTRA, default=list(WORKLOADS)
    )
    parser.add_argument("--worker", nargs=2, metavar=("WORKLOAD", "SIZE"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        worker(args.worker[0], int(args.worker[1]))
        return
    if args.base is None:
        parser.error("--base: a checkout of the revision to compare with")
    base = args.base.resolve()
    sizes = {
        "flat": args.flat_steps,
        "multi": args.multi_bot_steps,
        "eval": args.eval_episodes,
        "steer": args.flat_steps,
        "swap": args.multi_bot_steps,
    }
    units = {
        "flat": "us/step",
        "multi": "us/bot-step",
        "eval": "us/env step",
        "steer": "us/step",
        "swap": "us/bot-step",
    }
    print(f"A = this checkout ({HERE}), B = {base}; {args.rounds} rounds, A and B in turn")
    for workload in args.workloads:
        ratios, a_times, b_times = [], [], []
        for _ in range(args.rounds):
            a = measure(HERE, workload, sizes[workload])
            b = measure(base, workload, sizes[workload])
            ratios.append(a / b)
            a_times.append(a)
            b_times.append(b)
        print(
            f"{workload:6} A/B median {statistics.median(ratios):.3f} "
            f"(min {min(ratios):.3f}, max {max(ratios):.3f}); "
            f"A {1e6 * statistics.median(a_times):.2f}, B {1e6 * statistics.median(b_times):.2f} "
            f"{units[workload]}"
        )


if __name__ == "__main__":
    main()

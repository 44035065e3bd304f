"""Collection through the batched env, with the policy in the loop, against the bare env.

    python benchmarks/bench_batched.py [--worlds 16] [--world-steps 16000] [--rounds 2]
    python benchmarks/bench_batched.py --memory

With `--memory`, the resident memory a world adds, for the tasks that set
`bbbench.envs.batched.WORLD_MEMORY_MIB` (the largest, rounded up); no timing.

MultiBalance-v1 (4 bots), every bot driven by the PD baseline (its law in one numpy pass
over the rows, for every route), so that every route plays the same kind of episodes
(bots that stand, some falling at the crossings):

- **bare env**: `bbbench.make_parallel`, PD on the live bots' rows, one world at a
  time, in one process (one core) and in two processes side by side (two cores);
- **batched, policy in the loop**: `bbbench.marl.batched_env` of `--worlds` worlds,
  stepped by TorchRL's `step_and_maybe_reset` (partial resets included), with the
  recipe's actor (the neighbour encoder of `ippo.yml`, as BenchMARL builds it) run on
  every world's observations at each step before PD's actions replace its own; with
  1 worker (one core) and 2 workers (two cores).

A bot-step is a live bot stepped. Each round runs every route once, the order turning
round by round; the ratios are within a round. Run it on a quiet machine.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import statistics
import tempfile
import time

import numpy as np
import torch

TASK = "bbbench/MultiBalance-v1"


def pd_actor():
    """PD's discrete actions for a batch of observation rows, in one numpy pass (the same
    law as `bbbench.policies.PDController`, vectorized: the driver's cost stays out of
    the comparison; both routes use it)."""
    from bbbench.policies.controllers.pd import _CHANGES
    from bbbench.robots.twowheel import TWO_WHEEL

    radius, kp, kd, kv = TWO_WHEEL.wheel_radius, 40.0, 6.0, 20.0

    def act(rows: np.ndarray, rngs=None) -> np.ndarray:
        rows = np.asarray(rows, dtype=np.float64)
        pitch, rate, wheel, command, target = (rows[:, i] for i in range(5))
        velocity = radius * (wheel + rate)
        desired = target / radius + kp * pitch + kd * rate + kv * (velocity - target)
        return np.abs(_CHANGES[None, :] - (desired - command)[:, None]).argmin(axis=1)

    return act


def bare(world_steps: int, seed: int = 0) -> float:
    """Bot-steps per second of one world at a time under PD."""
    import bbbench

    actor = pd_actor()
    env = bbbench.make_parallel(TASK)
    observations, _ = env.reset(seed=seed)
    bot_steps = 0
    began = time.perf_counter()
    for _ in range(world_steps):
        bots = env.agents
        chosen = actor(np.stack([observations[bot] for bot in bots]), None)
        observations, *_ = env.step(dict(zip(bots, chosen, strict=True)))
        bot_steps += len(bots)
        if not env.agents:
            observations, _ = env.reset()
    seconds = time.perf_counter() - began
    env.close()
    return bot_steps / seconds


def _bare_worker(world_steps: int, seed: int, out) -> None:
    out.put(bare(world_steps, seed))


def bare_two_cores(world_steps: int) -> float:
    """Two bare envs in two processes at once: their bot-steps per second, summed."""
    context = multiprocessing.get_context("fork")
    out = context.Queue()
    processes = [
        context.Process(target=_bare_worker, args=(world_steps, seed, out)) for seed in (0, 1)
    ]
    for process in processes:
        process.start()
    rates = [out.get() for _ in processes]
    for process in processes:
        process.join()
    return sum(rates)


def recipe_policy(worlds: int, folder: str):
    """The IPPO recipe's policy for MultiBalance-v1 (the neighbour encoder and its
    sampling), as BenchMARL's `Experiment` builds it."""
    from pathlib import Path

    from bbbench.training.benchmarl.recipes import marl_recipe
    from bbbench.training.benchmarl.train import _quiet

    plan = marl_recipe("ippo", TASK)
    with _quiet():
        experiment = plan.build_experiment(plan.task_config(), 0, worlds, worlds, Path(folder))
        experiment.close()  # its own envs: only the policy is wanted
    return experiment.policy


def batched(worlds: int, world_steps: int, workers: int) -> float:
    """Bot-steps per second of the batched TorchRL env with the actor in the loop."""
    from bbbench.marl import batched_env

    actor = pd_actor()
    with tempfile.TemporaryDirectory() as folder:
        policy = recipe_policy(worlds, folder)
    env = batched_env(TASK, worlds=worlds, workers=workers)
    env.set_seed(0)
    state = env.reset()
    bot_steps = 0
    began = time.perf_counter()
    with torch.no_grad():
        for _ in range(world_steps // worlds):
            state = policy(state)  # the network's cost, every world at once
            observations = state["bot", "observation"].numpy()
            live = state["bot", "mask"].numpy()
            chosen = np.asarray(actor(observations.reshape(-1, observations.shape[-1]), None))
            state.set(("bot", "action"), torch.as_tensor(chosen.reshape(live.shape)))
            bot_steps += int(live.sum())
            _, state = env.step_and_maybe_reset(state)
    seconds = time.perf_counter() - began
    env.close()
    return bot_steps / seconds


MEMORY_TASKS = (
    "bbbench/MultiBalance-v1",
    "bbbench/MultiBumps-v1",
    "bbbench/BeamCarryBumps-v0",
    "bbbench/Swap-v0",
)


def _resident_mib() -> float:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    raise RuntimeError("no VmRSS in /proc/self/status: --memory needs Linux")


def _world_memory(task: str, worlds: int, out) -> None:
    """MiB of resident memory each world after the first adds, reset and held open (in a
    fresh process, so that no other task's freed blocks are reused)."""
    import bbbench

    held = [bbbench.make_parallel(task)]
    held[0].reset(seed=0)
    before = _resident_mib()
    for seed in range(1, worlds + 1):
        held.append(bbbench.make_parallel(task))
        held[-1].reset(seed=seed)
    out.put((_resident_mib() - before) / worlds)


def world_memory(worlds: int = 8) -> dict[str, float]:
    context = multiprocessing.get_context("spawn")
    report = {}
    for task in MEMORY_TASKS:
        out = context.Queue()
        process = context.Process(target=_world_memory, args=(task, worlds, out))
        process.start()
        report[task] = round(out.get(), 1)
        process.join()
    return report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, default=16)
    parser.add_argument("--world-steps", type=int, default=16_000)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--memory", action="store_true", help="MiB a world, no timing")
    args = parser.parse_args()
    if args.memory:
        print(json.dumps({"mib_a_world": world_memory()}, indent=2))
        return
    torch.set_num_threads(1)
    routes = {
        "bare_1_core": lambda: bare(args.world_steps),
        "bare_2_cores": lambda: bare_two_cores(args.world_steps),
        "batched_1_worker": lambda: batched(args.worlds, args.world_steps, 1),
        "batched_2_workers": lambda: batched(args.worlds, args.world_steps, 2),
    }
    rounds = []
    for index in range(args.rounds):
        names = list(routes)
        order = names if index % 2 == 0 else names[::-1]
        rates = {name: routes[name]() for name in order}
        rounds.append(
            {
                **{name: round(rate) for name, rate in rates.items()},
                "ratio_1_core": round(rates["batched_1_worker"] / rates["bare_1_core"], 3),
                "ratio_2_cores": round(rates["batched_2_workers"] / rates["bare_2_cores"], 3),
            }
        )
    report = {"task": TASK, "worlds": args.worlds, "world_steps": args.world_steps}
    report["rounds"] = rounds
    for key in ("ratio_1_core", "ratio_2_cores"):
        report[f"median_{key}"] = statistics.median(r[key] for r in rounds)
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()

"""Whole trainings on MultiBalance-v1 (4 bots) against the bare env, in bot-steps per
second: BenchMARL's IPPO with its shipped recipe, and the SB3 shared-PPO route.

    python benchmarks/bench_marl.py [--batches 4] [--rounds 2] [--recipe FILE]

- **bare env**: `bbbench.make_parallel` under PD, one world at a time, one core
  (`bench_batched.bare`), the yardstick;
- **IPPO**: `Experiment.run` of the shipped recipe (`bbbench/training/recipes/ippo.yml`,
  or `--recipe`) for `--batches` of its batches: collection from its batched worlds (in
  the recipe's worker processes), the updates on one torch thread, as `bbbench train`
  runs it;
- **SB3 shared PPO**: `model.learn` with `ppo.yml`'s recipe over `make_vec`'s worlds (4
  samples a world step), as many bot-steps.

Set-up (building envs, models, observation statistics) is outside the clock. A round
times every route, the order turning round by round; the ratios to the bare env are
within a round. Run it on a quiet machine.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

import torch
from bench_batched import bare

TASK = "bbbench/MultiBalance-v1"


def sb3_rate(bot_steps: int) -> float:
    from bbbench.training import recipe
    from bbbench.training.sb3.train import build_model, training_env

    plan = recipe("ppo", TASK)
    env = training_env(plan, [TASK], plan.n_envs, "discrete", seed=0)
    model = build_model(plan, env, seed=0)
    began = time.perf_counter()
    model.learn(total_timesteps=bot_steps)
    seconds = time.perf_counter() - began
    env.close()
    return bot_steps / seconds


def ippo_rate(
    batches: int, recipe_file: str | None, algorithm: str = "ippo", task_id: str = TASK
) -> float:
    """Bot-steps per second of `batches` iterations of `algorithm`'s recipe on `task_id`."""
    from bbbench.training.benchmarl.recipes import marl_recipe
    from bbbench.training.benchmarl.train import _quiet, observation_statistics

    plan = marl_recipe(algorithm, task_id, recipe_file)
    task = plan.task_config()
    task.observation_normalization = observation_statistics(
        task_id, task.env_kwargs, 0, plan.action_mode
    )
    frames = plan.batch() * batches
    with _quiet(), tempfile.TemporaryDirectory() as folder:
        experiment = plan.build_experiment(task, 0, frames, plan.n_envs, Path(folder))
        began = time.perf_counter()
        experiment.run()
        seconds = time.perf_counter() - began
        experiment.close()
    return frames * task.config["n_bots"] / seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batches", type=int, default=4)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--recipe", default=None, help="an ippo recipe file instead of ippo.yml")
    parser.add_argument("--bare-steps", type=int, default=16_000, help="world steps")
    args = parser.parse_args()
    torch.set_num_threads(1)
    from bbbench.training.benchmarl.recipes import marl_recipe

    plan = marl_recipe("ippo", TASK, args.recipe)
    bot_steps = plan.batch() * args.batches * plan.task_config().config["n_bots"]
    rounds = []
    for index in range(args.rounds):
        rates: dict[str, float] = {}
        order = ("bare", "ippo", "sb3") if index % 2 == 0 else ("sb3", "ippo", "bare")
        for route in order:
            if route == "bare":
                rates["bare"] = bare(args.bare_steps)
            elif route == "ippo":
                rates["ippo"] = ippo_rate(args.batches, args.recipe)
            else:
                rates["sb3"] = sb3_rate(bot_steps)
        rounds.append(
            {
                **{f"{name}_bot_steps_per_s": round(rate) for name, rate in rates.items()},
                "ippo_to_bare": round(rates["ippo"] / rates["bare"], 3),
                "sb3_to_bare": round(rates["sb3"] / rates["bare"], 3),
            }
        )
    report = {"task": TASK, "batches": args.batches, "bot_steps": bot_steps, "rounds": rounds}
    for key in ("ippo_to_bare", "sb3_to_bare"):
        report[f"median_{key}"] = statistics.median(r[key] for r in rounds)
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()

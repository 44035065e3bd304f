"""Training throughput on MultiBalance-v1 (4 bots): BenchMARL's IPPO against the SB3
shared-PPO route, in bot-steps per second.

    python bench/bench_marl.py [--bot-steps 32000] [--rounds 2] [--collect-steps 2000]

Both learn with their shipped recipe's rollout and update sizes (bbbench/training/
recipes/ippo.yml and ppo.yml), one torch thread, and nothing else timed: SB3's
`model.learn` over `make_vec`'s worlds (4 samples a world step), and BenchMARL's
`Experiment.run` over `bbbench.marl.tasks.BbbenchWrapper` (a frame a world step, 4 bots).
Set-up (building envs, models, observation statistics) is outside the clock. A round
times both, alternating which goes first; the ratio IPPO / SB3 is per round. Run it on
a quiet machine.

Collection alone, too: `--collect-steps` world steps of TorchRL's own
`PettingZooWrapper` against `bbbench.marl.tasks.BbbenchWrapper` (what BenchMARL trains
on), the same seeded random actions, resets included; the ratio is per round.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

import torch

TASK = "bbbench/MultiBalance-v1"


def sb3_seconds(bot_steps: int) -> float:
    from bbbench.training import build_model, recipe, training_env

    plan = recipe("ppo", TASK)
    env = training_env(plan, [TASK], plan.n_envs, "discrete", seed=0)
    model = build_model(plan, env, seed=0)
    began = time.perf_counter()
    model.learn(total_timesteps=bot_steps)
    seconds = time.perf_counter() - began
    env.close()
    return seconds


def ippo_seconds(bot_steps: int) -> float:
    from benchmarl.experiment import Experiment

    from bbbench.marl.training import _quiet, observation_statistics
    from bbbench.training import recipe

    plan = recipe("ippo", TASK)
    task = plan.task_config()
    task.observation_normalization = observation_statistics(TASK, task.env_kwargs, seed=0)
    bots = task.config["n_bots"]
    with _quiet(), tempfile.TemporaryDirectory() as folder:
        config = plan.experiment_config(bot_steps // bots, plan.n_envs, Path(folder))
        experiment = Experiment(
            task=task,
            algorithm_config=plan.algorithm_config(),
            model_config=plan.model_config(),
            critic_model_config=plan.model_config(critic=True),
            seed=0,
            config=config,
        )
        began = time.perf_counter()
        experiment.run()
        seconds = time.perf_counter() - began
        experiment.close()
    return seconds


def collect_seconds(wrapper: type, world_steps: int) -> float:
    """`world_steps` of `wrapper` over MultiBalance-v1, seeded random actions."""
    import bbbench

    options = {"use_mask": True, "done_on_any": False, "categorical_actions": True, "seed": 0}
    env = wrapper(bbbench.make_parallel(TASK, action_mode="discrete"), **options)
    spec = env.full_action_spec["bot", "action"]
    actions = torch.randint(
        9, (world_steps, *spec.shape), generator=torch.Generator().manual_seed(0)
    )
    state = env.reset()
    began = time.perf_counter()
    for action in actions:
        state = env.step(state.set(("bot", "action"), action))["next"]
        if state["done"].all():
            state = env.reset()
    seconds = time.perf_counter() - began
    env.close()
    return seconds


def collection_round(world_steps: int, first_ours: bool) -> dict[str, float]:
    from torchrl.envs.libs.pettingzoo import PettingZooWrapper

    from bbbench.marl.tasks import BbbenchWrapper

    order = (
        (BbbenchWrapper, PettingZooWrapper) if first_ours else (PettingZooWrapper, BbbenchWrapper)
    )
    seconds = {wrapper.__name__: collect_seconds(wrapper, world_steps) for wrapper in order}
    return {
        "torchrl_wrapper_s": round(seconds["PettingZooWrapper"], 2),
        "bbbench_wrapper_s": round(seconds["BbbenchWrapper"], 2),
        "speed_up": round(seconds["PettingZooWrapper"] / seconds["BbbenchWrapper"], 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bot-steps", type=int, default=32_000)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--collect-steps", type=int, default=2000)
    args = parser.parse_args()
    torch.set_num_threads(1)
    collection = [collection_round(args.collect_steps, i % 2 == 1) for i in range(args.rounds)]
    rounds = []
    for index in range(args.rounds):
        order = (sb3_seconds, ippo_seconds) if index % 2 == 0 else (ippo_seconds, sb3_seconds)
        seconds = {run.__name__: run(args.bot_steps) for run in order}
        sb3 = args.bot_steps / seconds["sb3_seconds"]
        ippo = args.bot_steps / seconds["ippo_seconds"]
        rounds.append(
            {
                "sb3_bot_steps_per_s": round(sb3),
                "ippo_bot_steps_per_s": round(ippo),
                "ratio": round(ippo / sb3, 3),
            }
        )
    report = {"task": TASK, "bot_steps": args.bot_steps, "rounds": rounds}
    report["median_ratio"] = statistics.median(r["ratio"] for r in rounds)
    report["collection"] = {"world_steps": args.collect_steps, "rounds": collection}
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()

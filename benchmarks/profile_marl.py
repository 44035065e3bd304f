"""Where a BenchMARL training iteration's wall time goes, on one multi-bot task.

    python benchmarks/profile_marl.py [--task bbbench/MultiBalance-v1] [--algo ippo]
                                 [--batches 4] [--recipe FILE]

Runs `--batches` training iterations of the shipped recipe (`bbbench/training/recipes/
<algo>.yml`, or `--recipe`), as `bbbench train` builds them (observation statistics and
set-up outside the clock, no evaluation), with timers around the parts of an iteration.
Each second is counted once, in the innermost part it was spent in:

| part                 | what is timed                                                     |
|----------------------|-------------------------------------------------------------------|
| physics              | every call into pybullet (step, reads, motors, constraints)       |
| scenario             | the scenario's `observe`, `outcome` and `before_step`, less physics |
| env API              | bbbench's env `step` and `reset` (PettingZoo or batched), less the above |
| TorchRL env          | TorchRL's env machinery and bbbench's TorchRL face, less the above |
| policy inference     | the policy's forward calls during collection                      |
| collector            | the rest of TorchRL's collector (its rollout loop)                |
| GAE                  | the algorithm's `process_batch` (values, GAE, advantage masking)  |
| updates              | the minibatch updates (`Experiment._optimizer_loop`)              |
| other                | the rest of the iteration (logging, the replay buffer's extend)   |

Timers cost about half a microsecond a call, which falls mostly on physics (several
pybullet calls a bot-step): the shares are of the timed run's wall time, which is
printed beside the same run untimed.
"""

from __future__ import annotations

import argparse
import functools
import inspect
import json
import tempfile
import time
import types
from pathlib import Path

import pybullet
import torch
from pybullet_utils import bullet_client


class Parts:
    """Exclusive wall time per named part: a call's time goes to its innermost part."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.stack: list[list] = []  # [name, began, inner seconds]

    def wrap(self, function, name: str, unless: tuple[str, ...] = ()):
        parts = self

        @functools.wraps(function)
        def timed(*args, **kwargs):
            if unless and any(frame[0] in unless for frame in parts.stack):
                return function(*args, **kwargs)
            frame = [name, time.perf_counter(), 0.0]
            parts.stack.append(frame)
            try:
                return function(*args, **kwargs)
            finally:
                parts.stack.pop()
                spent = time.perf_counter() - frame[1]
                parts.seconds[name] = parts.seconds.get(name, 0.0) + spent - frame[2]
                if parts.stack:
                    parts.stack[-1][2] += spent

        return timed

    def patch(self, owner, attribute: str, name: str, unless: tuple[str, ...] = ()) -> None:
        """Time `owner.attribute` (its own, or the one it inherits) as `name`."""
        if hasattr(owner, attribute):
            setattr(owner, attribute, self.wrap(getattr(owner, attribute), name, unless))


def instrument(parts: Parts) -> None:
    """Timers around every part (before any world connects: `World` binds pybullet's
    step when it connects)."""
    from benchmarl.experiment import Experiment
    from tensordict.nn import TensorDictModule, TensorDictSequential
    from torchrl.collectors import SyncDataCollector
    from torchrl.envs import EnvBase

    import bbbench.envs.multi as multi
    from bbbench.marl import algorithms
    from bbbench.tasks import scenarios

    for attribute in dir(pybullet):
        if not attribute.startswith("_") and inspect.isbuiltin(getattr(pybullet, attribute)):
            parts.patch(pybullet, attribute, "physics")
    # BulletClient passes its client id to pybullet's builtins only: the timed ones too.
    bullet_client.inspect = types.SimpleNamespace(
        isbuiltin=lambda function: inspect.isbuiltin(function) or hasattr(function, "__wrapped__")
    )
    for scenario in scenarios.SCENARIOS.values():
        for attribute in ("observe", "outcome", "before_step"):
            parts.patch(scenario, attribute, "scenario")
    for attribute in ("step", "reset"):
        parts.patch(multi.MultiBalanceEnv, attribute, "env API")
    batched = _batched_env_class()
    if batched is not None:
        for attribute in ("step", "reset", "step_worlds", "reset_worlds"):
            parts.patch(batched, attribute, "env API")
    for owner in {EnvBase, *_torchrl_faces()}:
        for attribute in ("step", "reset", "step_and_maybe_reset", "_step", "_reset"):
            parts.patch(owner, attribute, "TorchRL env")
    for module in (TensorDictSequential, TensorDictModule):
        parts.patch(module, "forward", "policy inference", unless=("updates", "GAE"))
    parts.patch(SyncDataCollector, "rollout", "collector")
    parts.patch(Experiment, "_optimizer_loop", "updates")
    for algorithm in (algorithms.MaskedIppo, algorithms.MaskedMappo):
        parts.patch(algorithm, "process_batch", "GAE")


def _batched_env_class():
    try:
        from bbbench.envs.batched import BatchedEnv
    except ImportError:  # before the batched env
        return None
    return BatchedEnv


def _torchrl_faces() -> list[type]:
    try:
        from bbbench.marl import family as tasks
    except ImportError:  # before the house (issue 51): bbbench.marl.tasks
        from bbbench.marl import tasks

    return [
        value
        for value in vars(tasks).values()
        if isinstance(value, type)
        and value.__module__.startswith("bbbench")
        and hasattr(value, "_step")
    ]


def run(
    task_id: str, algorithm: str, batches: int, recipe_file: str | None, parts: Parts | None = None
) -> tuple[float, int]:
    """Seconds of `Experiment.run` for `batches` iterations, and its world steps; `parts`
    counts from the run's start (set-up off its clock too)."""
    from benchmarl.experiment import Experiment

    from bbbench.training.benchmarl import recipes
    from bbbench.training.benchmarl.recipes import marl_recipe
    from bbbench.training.benchmarl.train import _quiet, observation_statistics

    plan = marl_recipe(algorithm, task_id, recipe_file)
    task = plan.task_config()
    keywords = getattr(task, "env_kwargs", task.config)  # (before the batched env: config)
    task.observation_normalization = observation_statistics(task_id, keywords, 0, plan.action_mode)
    batch = int(plan.experiment.get("on_policy_collected_frames_per_batch", 6000))
    frames = batch * batches
    with _quiet(), tempfile.TemporaryDirectory() as folder:
        # Built by hand, not `plan.build_experiment`: this runs on the code before it too
        # (before the updates' own threads, `PhasedExperiment`, BenchMARL's `Experiment`).
        experiment = getattr(recipes, "PhasedExperiment", Experiment)(
            task=task,
            algorithm_config=plan.algorithm_config(),
            model_config=plan.model_config(),
            critic_model_config=plan.model_config(critic=True),
            seed=0,
            config=plan.experiment_config(frames, plan.n_envs, Path(folder)),
        )
        if parts is not None:
            parts.seconds.clear()
        began = time.perf_counter()
        experiment.run()
        seconds = time.perf_counter() - began
        experiment.close()
    return seconds, frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="bbbench/MultiBalance-v1")
    parser.add_argument("--algo", default="ippo")
    parser.add_argument("--batches", type=int, default=4)
    parser.add_argument("--recipe", default=None)
    parser.add_argument("--threads", type=int, default=1, help="torch's threads")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    run(args.task, args.algo, 1, args.recipe)  # imports and first calls: off the clock
    untimed, frames = run(args.task, args.algo, args.batches, args.recipe)
    parts = Parts()
    instrument(parts)
    timed, _ = run(args.task, args.algo, args.batches, args.recipe, parts)
    parts.seconds["other"] = timed - sum(parts.seconds.values())
    report = {
        "task": args.task,
        "algorithm": args.algo,
        "world_steps": frames,
        "untimed_s": round(untimed, 2),
        "timed_s": round(timed, 2),
        "shares": {
            name: round(seconds / timed, 3)
            for name, seconds in sorted(parts.seconds.items(), key=lambda item: -item[1])
        },
    }
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()

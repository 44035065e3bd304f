"""The stable-baselines3 route: `bbbench train --algo ppo` (sac, dqn, ...).

Hyperparameters come from the rl-zoo3 files in `bbbench/training/recipes/`
(`bbbench.training.sb3.recipes`). Every `eval_freq` steps the policy plays a fixed set
of *training* seeds of each task (never an eval seed; `bbbench.training.sb3.callbacks`);
the best one is kept. A recipe that trains inside `VecNormalize` (`normalize`) also
writes the statistics of the kept policy where rl-zoo3 does and `bbbench eval` looks:
`policy.zip` -> `policy/vecnormalize.pkl`.
"""

from __future__ import annotations

import io
import json
import os
import platform
import re
import tempfile
import time
import zipfile
from collections.abc import Callable
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch

from bbbench.evaluation import evaluate
from bbbench.files import write_atomic
from bbbench.policies import load_policy
from bbbench.policies.sb3.algorithms import by_key
from bbbench.training.beside import trainings_beside
from bbbench.training.checks import schedule
from bbbench.training.logs import Trained, write_logs
from bbbench.training.sb3.callbacks import TrainingEvaluation
from bbbench.training.sb3.recipes import Recipe, recipe, statistics_path
from bbbench.training.seeds import evaluation_seeds

_ADDRESS = re.compile(r" at 0x[0-9a-f]+")


def train_sb3(
    tasks: list[str],
    key: str,
    algorithm: str,
    mode: str,
    out: str | Path,
    steps: int | None = None,
    seed: int = 0,
    n_envs: int | None = None,
    log_dir: str | Path | None = None,
    eval_freq: int | None = None,
    final_episodes: int | None = None,
    on_progress: Callable[[int, int, dict | None], None] | None = None,
    recipe_file: str | Path | None = None,
) -> Trained:
    """Train the stable-baselines3 `algorithm` on `tasks` (a request `check_request`
    passed: its recipe `key`, its action `mode`) and write the best policy to `out`, a
    zip, with the logs beside it (`bbbench.training.train` says the rest)."""
    plan = recipe(algorithm, key, recipe_file)
    run = schedule(plan, algorithm, tasks, out, n_envs, None, steps, log_dir, eval_freq)
    budget, n_envs, out, log_dir, eval_freq = (
        run.budget,
        run.n_envs,
        run.out,
        run.log_dir,
        run.eval_freq,
    )
    statistics = statistics_path(out, plan)

    torch.set_num_threads(1)  # the same bytes on every run, and no oversubscription
    began = time.perf_counter()
    env = training_env(plan, tasks, n_envs, mode, seed)
    model = build_model(plan, env, seed)
    with (
        trainings_beside() as beside,
        tempfile.TemporaryDirectory(dir=log_dir, prefix=".training-") as scratch,
    ):
        best = Path(scratch) / "best.zip"
        callback = TrainingEvaluation(tasks, mode, eval_freq, best, began, on_progress, budget)
        model.learn(total_timesteps=budget, callback=callback)
        callback.evaluate_now(model)  # the end of the budget is a point of the curve
        env.close()
        callback.close()
        data = reproducible_zip(best.read_bytes())
        kept_statistics = callback.best_statistics.read_bytes() if statistics else None
    seconds = time.perf_counter() - began
    write_atomic(out, data)
    if statistics is not None:
        statistics.parent.mkdir(exist_ok=True)
        write_atomic(statistics, kept_statistics)

    results = evaluate(load_policy(out), tasks, episodes=final_episodes).document
    record = {
        "tasks": tasks,
        "action_mode": mode,
        "seed": seed,
        "steps": budget,
        "n_envs": n_envs,
        "eval_freq": eval_freq,
        "evaluation_seeds": {task_id: evaluation_seeds(task_id) for task_id in tasks},
        "best": max(callback.curve, key=lambda point: point["mean"]),
        "wall_time_s": round(seconds, 1),
        "trainings_beside": beside.record(),
        "machine": f"{platform.machine()}, {os.cpu_count()} CPU(s), {platform.processor()}",
        "recipe": plan.record(),
        **({"statistics": str(statistics)} if statistics is not None else {}),
    }
    write_logs(log_dir, callback.curve, tasks, algorithm, record, results)
    return Trained(out, log_dir, statistics, callback.curve, results, seconds, plan)


def training_env(plan: Recipe, tasks: list[str], n_envs: int, mode: str, seed: int):
    """The VecEnv a recipe trains in: `n_envs` envs of the task (worlds of bots for a
    multi-bot task; for several tasks, sub-env i plays task i mod len(tasks)), seeded."""
    from stable_baselines3.common.monitor import Monitor  # lazy: stable_baselines3
    from stable_baselines3.common.vec_env import DummyVecEnv

    from bbbench.vec import make_vec  # lazy: stable_baselines3

    if len(tasks) == 1:
        env = make_vec(tasks[0], n_envs=n_envs, action_mode=mode)
    else:  # sub-env i plays task i mod len(tasks), each in a Monitor
        plays = [tasks[i % len(tasks)] for i in range(n_envs)]
        env = DummyVecEnv(
            [lambda task=task: Monitor(gym.make(task, action_mode=mode)) for task in plays]
        )
    env.seed(seed)
    if plan.normalize is not None:
        from stable_baselines3.common.vec_env import VecNormalize  # lazy: stable_baselines3

        gamma = plan.hyperparameters.get("gamma", 0.99)  # rl-zoo3 passes the recipe's
        env = VecNormalize(env, gamma=gamma, **plan.normalize)
    return env


def build_model(plan: Recipe, env, seed: int):
    """The stable-baselines3 model of `plan` on `env`, seeded, on the CPU."""
    from stable_baselines3.common.noise import NormalActionNoise  # lazy: stable_baselines3

    extra = {}
    if plan.noise_std is not None:
        size = env.action_space.shape[0]
        extra["action_noise"] = NormalActionNoise(np.zeros(size), plan.noise_std * np.ones(size))
    return by_key(plan.algorithm).model_class()(
        plan.policy,
        env,
        seed=seed,
        device="cpu",
        verbose=0,
        policy_kwargs=plan.policy_kwargs,
        **plan.hyperparameters,
        **extra,
    )


def reproducible_zip(data: bytes) -> bytes:
    """A stable-baselines3 zip with the same bytes for the same training: members with
    a fixed date, without the two fields that hold wall-clock times (`start_time` and
    `ep_info_buffer`, which `learn` sets up again), and with the memory addresses in
    the descriptions of pickled values zeroed. SB3's `load` reads it."""
    source = zipfile.ZipFile(io.BytesIO(data))
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as target:
        for info in source.infolist():
            content = source.read(info.filename)
            if info.filename == "data":
                fields = json.loads(content)
                for timed in ("start_time", "ep_info_buffer"):
                    fields.pop(timed, None)
                # The descriptions beside pickled values name objects by memory address.
                text = _ADDRESS.sub(" at 0x0", json.dumps(fields, indent=4))
                content = text.encode()
            member = zipfile.ZipInfo(info.filename, date_time=(1980, 1, 1, 0, 0, 0))
            member.compress_type = zipfile.ZIP_DEFLATED
            member.external_attr = 0o644 << 16
            target.writestr(member, content)
    return buffer.getvalue()

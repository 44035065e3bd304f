"""`bbbench train`: train a policy on a task with the recipe shipped for it.

    from bbbench.training import train
    result = train(["bbbench/FlatBalance-v1"], "ppo", out="policy.zip", seed=0)

Hyperparameters come from the rl-zoo3 files in `bbbench/training/recipes/`.
Training is seeded and single-threaded (torch on the CPU, one thread), so the same
call on one machine writes the same zip bytes. Every `eval_freq` steps the policy
plays a fixed set of *training* seeds of each task (never an eval seed); the best
one is kept. Written beside the zip (or in `log_dir`): `curve.json` and `curve.png`
(the learning curve), `train.json` (the recipe, seed, budget, time, machine) and
`results.json` (the final `bbbench eval` document on the task's eval seeds). A recipe
that trains inside `VecNormalize` (`normalize`) also writes the statistics of the kept
policy where rl-zoo3 does and `bbbench eval` looks: `policy.zip` ->
`policy/vecnormalize.pkl`.
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
from collections.abc import Callable, Sequence
from pathlib import Path

import gymnasium as gym
import numpy as np

from bbbench.evaluation import evaluate
from bbbench.files import check_output_path, write_atomic
from bbbench.policies import load_policy
from bbbench.policies.algorithms import by_key, unknown
from bbbench.policies.vecnormalize import STATISTICS_FILE
from bbbench.tasks.suite import list_tasks, spec
from bbbench.training.beside import trainings_beside
from bbbench.training.logs import Trained, write_logs
from bbbench.training.recipes import (
    MARL_TRAINABLE,
    MIX,
    TRAINABLE,
    Recipe,
    check_collection,
    check_policy_path,
    recipe,
)
from bbbench.training.seeds import evaluation_seeds

_ADDRESS = re.compile(r" at 0x[0-9a-f]+")


def check_request(
    task_ids: Sequence[str],
    algorithm: str,
    action_mode: str | None,
    steps: int | None,
    recipe_file: str | Path | None = None,
) -> tuple[list[str], str, str]:
    """The tasks (IDs normalized), recipe key and action mode of a training request;
    `ValueError` saying what is wrong and what to do."""
    if algorithm not in TRAINABLE + MARL_TRAINABLE:
        raise ValueError(unknown("algorithm", algorithm, TRAINABLE + MARL_TRAINABLE))
    if not task_ids:
        raise ValueError("give a task ID (bbbench list shows them)")
    tasks = list(dict.fromkeys(spec(task_id).id for task_id in task_ids))
    if steps is not None and steps < 1:
        raise ValueError(f"--steps must be at least 1, got {steps}")
    if algorithm in MARL_TRAINABLE:
        return _check_marl_request(tasks, algorithm, action_mode, recipe_file)
    if len(tasks) > 1 and any(spec(t).multi_agent for t in tasks):
        raise ValueError(
            "several tasks train one generalist on single-bot tasks; a multi-bot task "
            "trains on its own"
        )
    robots = {spec(t).robot_model for t in tasks}
    if len(robots) > 1:
        raise ValueError(
            f"one policy trains on one robot's tasks: {', '.join(tasks)} play "
            f"{' and '.join(sorted(robot.name for robot in robots))}"
        )
    (robot,) = robots
    # The algorithm's first mode the robot takes (PPO: discrete on the two-wheel bot,
    # continuous on the wheel-legged robot).
    modes = [m for m in by_key(algorithm).action_modes if m in robot.action_modes]
    mode = action_mode or (modes[0] if modes else by_key(algorithm).action_modes[0])
    if mode not in robot.action_modes:
        raise ValueError(
            f"the {robot.name} robot takes {' or '.join(robot.action_modes)} actions, not "
            f"{mode}: use --action-mode {robot.default_action_mode}"
            + (
                ""
                if modes
                else f", with an algorithm that learns {robot.default_action_mode} actions"
            )
        )
    modes = by_key(algorithm).action_modes
    if mode not in modes:
        others = [a for a in TRAINABLE if mode in by_key(a).action_modes]
        raise ValueError(
            f"{algorithm.upper()} learns {' or '.join(modes)} actions, not {mode}: "
            f"use --action-mode {modes[0]}, or an algorithm for {mode} actions "
            f"({', '.join(others)})"
        )
    key = MIX if len(tasks) > 1 else tasks[0]
    recipe(algorithm, key, recipe_file)  # a task without a recipe (an older version) is refused
    return tasks, key, mode


def _check_marl_request(tasks, algorithm, action_mode, recipe_file) -> tuple[list[str], str, str]:
    name = algorithm.upper()
    if len(tasks) > 1:
        raise ValueError(f"{name} trains on one multi-bot task at a time, got {', '.join(tasks)}")
    (task,) = tasks
    if not spec(task).multi_agent:
        multi = [t for t in list_tasks(latest=True) if spec(t).multi_agent]
        raise ValueError(
            f"{task} is a single-bot task: {name} trains the bots of a multi-bot task "
            f"({', '.join(multi)}); train {task} with --algo ppo or sac"
        )
    if action_mode not in (None, "discrete"):
        raise ValueError(f"{name} trains discrete actions (Discrete(9)): drop --action-mode")
    recipe(algorithm, task, recipe_file)
    return tasks, task, "discrete"


def train(
    task_ids: Sequence[str],
    algorithm: str,
    out: str | Path,
    action_mode: str | None = None,
    steps: int | None = None,
    seed: int = 0,
    n_envs: int | None = None,
    log_dir: str | Path | None = None,
    eval_freq: int | None = None,
    final_episodes: int | None = None,
    on_progress: Callable[[int, int, dict | None], None] | None = None,
    recipe_file: str | Path | None = None,
    workers: int | None = None,
) -> Trained:
    """Train `algorithm` on `task_ids` (several: one generalist on all of them) with its
    recipe (from `recipe_file`, else the shipped one); write the best policy to `out`
    and the logs beside it. IPPO and MAPPO train with BenchMARL (`bbbench.marl.training`)
    and write their last policy, as ONNX.

    `steps` and `n_envs` default to the recipe's (a budget is at least one rollout, see
    `check_collection`); `eval_freq` to a tenth of the budget, and at least a rollout;
    `final_episodes` (the closing `bbbench eval`) to every eval seed. `workers` (IPPO and
    MAPPO): the processes that step the worlds, default the recipe's.
    `on_progress(steps, total, latest evaluation point or None)` is called as it goes.
    """
    import torch  # lazy: torch, stable_baselines3, for training only

    tasks, key, mode = check_request(task_ids, algorithm, action_mode, steps, recipe_file)
    if seed < 0:
        raise ValueError(f"--seed must be >= 0, got {seed}")
    if algorithm in MARL_TRAINABLE:
        from bbbench.marl.training import train_marl  # lazy: benchmarl, optional

        return train_marl(
            key,
            algorithm,
            out,
            steps=steps,
            seed=seed,
            n_envs=n_envs,
            log_dir=log_dir,
            eval_freq=eval_freq,
            final_episodes=final_episodes,
            on_progress=on_progress,
            recipe_file=recipe_file,
            workers=workers,
        )
    from bbbench.training.callbacks import TrainingEvaluation  # lazy: stable_baselines3

    plan = recipe(algorithm, key, recipe_file)
    budget, batch, _ = check_collection(plan, tasks, n_envs, workers, steps)
    n_envs = n_envs or plan.n_envs
    out = check_policy_path(algorithm, out)
    statistics = statistics_path(out, plan)
    log_dir = Path(log_dir) if log_dir is not None else out.parent
    log_dir.mkdir(parents=True, exist_ok=True)
    check_output_path(log_dir / "curve.json", "--log")
    eval_freq = max(eval_freq or budget // 10, batch)

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


def statistics_path(out: str | Path, plan: Recipe) -> Path | None:
    """Where the VecNormalize statistics of the policy `out` go if `plan` trains inside
    VecNormalize: rl-zoo3's layout, which `bbbench eval` finds on its own (`policy.zip`
    -> `policy/vecnormalize.pkl`). None for a recipe without; `ValueError` if a file is
    in the way."""
    if plan.normalize is None:
        return None
    out = Path(out)
    statistics = out.parent / out.stem / STATISTICS_FILE
    if statistics.parent.exists() and not statistics.parent.is_dir():
        raise ValueError(
            f"--out {out}: its recipe trains inside VecNormalize, whose statistics go to "
            f"{statistics}, but {statistics.parent} is a file: choose another --out"
        )
    return statistics


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

"""`bbbench train`: train a policy on a task with the recipe shipped for it.

    from bbbench.training import train
    result = train(["bbbench/FlatBalance-v1"], "ppo", out="policy.zip", seed=0)

This module is what both routes share: the request checked against the table of
algorithms (`bbbench.training.algorithms`), the recipe read, the policy path and the
collection checked, then the route's own loop: `bbbench.training.sb3` (a zip) or
`bbbench.training.benchmarl` (ONNX). Every route writes the same logs beside the policy
(`bbbench.training.logs`): `curve.json`, `curve.png`, `train.json`, `results.json`.
Training is seeded and single-threaded (torch on the CPU, one thread), so the same call
on one machine writes the same bytes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from bbbench.tasks.suite import agent_layout, agent_spaces, list_tasks, spec
from bbbench.training.algorithms import ALGORITHMS, BENCHMARL, TRAINABLE, trainable
from bbbench.training.logs import Trained
from bbbench.training.sb3.recipes import MIX
from bbbench.training.sb3.recipes import recipe as sb3_recipe


def check_request(
    task_ids: Sequence[str],
    algorithm: str,
    action_mode: str | None,
    steps: int | None,
    recipe_file: str | Path | None = None,
) -> tuple[list[str], str, str]:
    """The tasks (IDs normalized), recipe key and action mode of a training request;
    `ValueError` saying what is wrong and what to do."""
    algo = trainable(algorithm)
    if not task_ids:
        raise ValueError("give a task ID (bbbench list shows them)")
    tasks = list(dict.fromkeys(spec(task_id).id for task_id in task_ids))
    if steps is not None and steps < 1:
        raise ValueError(f"--steps must be at least 1, got {steps}")
    if algo.route == BENCHMARL:
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
    layouts = {t: agent_layout(t) for t in tasks}
    if len(set(layouts.values())) > 1:  # the same robot, another scenario's observation
        shown = ", ".join(f"{t} {len(layout)} values" for t, layout in layouts.items())
        raise ValueError(
            f"one policy trains on tasks whose observations mean the same: {shown}, laid out "
            f"differently; train a policy per task, or mix tasks of one layout (`bbbench list "
            f"TASK` shows a task's)"
        )
    # The algorithm's first mode the robot takes (PPO: discrete on the two-wheel bot,
    # continuous on the wheel-legged robot).
    modes = [m for m in algo.action_modes if m in robot.action_modes]
    mode = action_mode or (modes[0] if modes else algo.action_modes[0])
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
    modes = algo.action_modes
    if mode not in modes:
        others = [a for a in TRAINABLE if mode in ALGORITHMS[a].action_modes]
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
    mixed = spec(task).mixed
    if mixed and trainable(algorithm).recurrent:
        raise ValueError(
            f"{task} is a mixed team, whose policy file (a team file) carries no "
            f"recurrent state: train it with {algorithm.removesuffix('-gru')}"
        )
    mode = recipe(algorithm, task, recipe_file).action_mode  # continuous on a mixed team
    if action_mode not in (None, mode):
        if mixed:
            raise ValueError(
                f"{task} is a mixed team ({' and '.join(spec(task).robots)} robots): {name} "
                f"trains the continuous actions they share: drop --action-mode"
            )
        space = agent_spaces(task, mode)[1]
        raise ValueError(
            f"{name}'s recipe for {task} trains {mode} actions ({space} on {task}): drop "
            f"--action-mode, or give a --recipe whose experiment sets "
            f"prefer_continuous_actions: {str(action_mode == 'continuous').lower()}"
        )
    return tasks, task, mode


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
    and the logs beside it. IPPO and MAPPO train with BenchMARL (`bbbench.training.benchmarl`)
    and write their last policy, as ONNX.

    `steps` and `n_envs` default to the recipe's (a budget is at least one rollout, see
    `check_collection`); `eval_freq` to a tenth of the budget, and at least a rollout;
    `final_episodes` (the closing `bbbench eval`) to every eval seed. `workers` (IPPO and
    MAPPO): the processes that step the worlds, default the recipe's.
    `on_progress(steps, total, latest evaluation point or None)` is called as it goes.
    """
    tasks, key, mode = check_request(task_ids, algorithm, action_mode, steps, recipe_file)
    if seed < 0:
        raise ValueError(f"--seed must be >= 0, got {seed}")
    shared = {
        "steps": steps,
        "seed": seed,
        "n_envs": n_envs,
        "log_dir": log_dir,
        "eval_freq": eval_freq,
        "final_episodes": final_episodes,
        "on_progress": on_progress,
        "recipe_file": recipe_file,
    }
    if trainable(algorithm).route == BENCHMARL:
        from bbbench.training.benchmarl.train import train_marl  # lazy: benchmarl, optional

        return train_marl(key, algorithm, out, workers=workers, **shared)
    from bbbench.training.sb3.train import train_sb3  # lazy: stable_baselines3

    return train_sb3(tasks, key, algorithm, mode, out, **shared)


def recipe(algorithm: str, key: str, file: str | Path | None = None):
    """`algorithm`'s recipe for `key` (from `file`, else the shipped one): an SB3
    `Recipe`, or a `MarlRecipe` for a BenchMARL algorithm; `ValueError` naming the ones
    there are."""
    if trainable(algorithm).route == BENCHMARL:
        return marl_recipe(algorithm, key, file)
    return sb3_recipe(algorithm, key, file)


def marl_recipe(algorithm: str, key: str, file: str | Path | None = None):
    """A BenchMARL recipe (`bbbench.training.benchmarl.recipes`); `ValueError` if BenchMARL
    is missing."""
    try:
        from bbbench.training.benchmarl.recipes import marl_recipe as read  # lazy: benchmarl
    except ImportError as error:
        raise ValueError(
            f"{algorithm.upper()} trains with BenchMARL, which is not installed ({error}): "
            f"pip install 'bbbench[marl]'"
        ) from None
    return read(algorithm, key, file)

"""A results document in marl-eval's raw-data format (`bbbench eval --marl-eval OUT`).

marl-eval (InstaDeep's `id-marl-eval`, the statistics BenchMARL reports with)
reads one JSON of runs:

    {env: {task: {algorithm: {run: {"step_0": {"step_count": N, metric: [...]},
                                    "absolute_metrics": {metric: [...]}}}}}}

bbbench writes the environment `bbbench`, one task per bbbench task (`MultiBalance-v1`),
the policy's algorithm (commas dropped: marl-eval splits on them), one run named after
the policy's training seed (`run_<seed>`, from the file's `bbbench.training_seed`), so
that the files of several seeds and several algorithms merge into one document that
marl-eval's `create_matrices_for_rliable` takes (it wants the same run names for every
algorithm); a file that does not say its seed is named after its SHA-256
(`run_<first 12 hex digits>`), a built-in after itself,
and one logging step, at the policy's training steps (0 when it does not say), holding
each evaluation episode's value of:

- `return`: the episode's return (per bot, on a multi-bot task: the mean over its bots);
- `normalized_return`: the same normalized as the board does (0 random, 1 the maximum);
- `success`: 1 if no bot fell, else 0.

`absolute_metrics` holds the same lists: the evaluation of the final policy, on every
evaluation seed asked for (marl-eval's absolute metric).
"""

from __future__ import annotations

from typing import Any

from bbbench.evaluation.results import normalized
from bbbench.tasks.suite import spec

ENVIRONMENT = "bbbench"


def marl_eval_document(
    results: dict[str, Any], training_steps: int | None = None, training_seed: int | None = None
) -> dict:
    """marl-eval's raw data for a `bbbench eval` results document."""
    policy = results["policy"]
    algorithm = policy["algorithm"].replace(",", "") or "policy"
    if training_seed is not None:
        run = f"run_{training_seed}"
    elif policy["sha256"]:
        run = f"run_{policy['sha256'][:12]}"
    else:
        run = f"run_{policy['name']}"
    tasks: dict[str, Any] = {}
    for block in results["tasks"]:
        task = spec(block["task"])
        episodes = block["episodes"]
        metrics = {
            "return": [episode["return"] for episode in episodes],
            "normalized_return": [normalized(episode["return"], task) for episode in episodes],
            "success": [1.0 if episode["success"] else 0.0 for episode in episodes],
        }
        tasks[block["task"].removeprefix("bbbench/")] = {
            algorithm: {
                run: {
                    "step_0": {"step_count": int(training_steps or 0), **metrics},
                    "absolute_metrics": metrics,
                }
            }
        }
    return {ENVIRONMENT: tasks}

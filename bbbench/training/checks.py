"""What a training's request must be, for either route: the policy file it writes, and
the budget it collects in whole batches."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from bbbench.files import check_output_path
from bbbench.training.algorithms import trainable


def check_policy_path(algorithm: str, out: str | Path) -> Path:
    """`out` as the policy file `algorithm` writes: a name ending in .zip
    (stable-baselines3) or .onnx (IPPO, MAPPO), in a folder it can write, so that it is
    never taken for one of the logs written beside it (curve.json, train.json ...);
    `ValueError` saying what to give."""
    suffix = trainable(algorithm).suffix
    written = "an ONNX policy" if suffix == ".onnx" else "a zip policy"
    if Path(str(out)).suffix != suffix:
        raise ValueError(
            f"--out {out}: {algorithm.upper()} writes {written}: give a file name ending in "
            f"{suffix} (curve.json, curve.png, train.json and results.json go beside it)"
        )
    return check_output_path(out, "--out")


def whole_batches(steps: int, batch: int) -> tuple[int, str | None]:
    """A budget of `steps` as a training honours it: at least one batch (`batch` steps,
    the least a training collects before it learns); and the note that says so when it
    is rounded up, else None."""
    if steps >= batch:
        return steps, None
    return batch, (
        f"--steps {steps:,} is less than one batch of the recipe ({batch:,} steps collected "
        f"before it learns): training one batch, {batch:,} steps"
    )


def check_collection(
    plan, tasks: Sequence[str], n_envs: int | None, workers: int | None, steps: int | None
) -> tuple[int, int, str | None]:
    """How a training of `plan` (either route's recipe) collects, checked: its budget
    (`steps`, default the recipe's, at least one batch), its batch (`plan.batch_of`: a
    rollout of every env; IPPO's and MAPPO's world steps a batch), and the note that says
    the budget was rounded up (else None). `ValueError` for envs or worker processes the
    recipe cannot take."""
    if n_envs is not None and n_envs < 1:
        raise ValueError(f"--n-envs must be at least 1, got {n_envs}")
    batch = plan.batch_of(tasks, n_envs or plan.n_envs, workers)
    budget, note = whole_batches(steps or plan.n_timesteps, batch)
    return budget, batch, note

"""What a training's request must be, for either route: the policy file it writes, and
the budget it collects in whole batches."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

from bbbench.files import check_output_path
from bbbench.tasks import SUITE
from bbbench.training.algorithms import trainable


def policy_suffix(algorithm: str, tasks: Sequence[str] = ()) -> str:
    """How the policy file `algorithm` writes on `tasks` ends: .zip (stable-baselines3),
    .onnx (IPPO, MAPPO), or .zip for IPPO and MAPPO on a mixed team (a team file: an ONNX
    policy per robot, `bbbench.policies.onnx.team`)."""
    suffix = trainable(algorithm).suffix
    if suffix == ".onnx" and any(task in SUITE and SUITE[task].mixed for task in tasks):
        return ".zip"
    return suffix


def check_policy_path(algorithm: str, out: str | Path, tasks: Sequence[str] = ()) -> Path:
    """`out` as the policy file `algorithm` writes on `tasks` (`policy_suffix`), in a
    folder it can write, so that it is never taken for one of the logs written beside it
    (curve.json, train.json ...); `ValueError` saying what to give."""
    suffix = policy_suffix(algorithm, tasks)
    if suffix != trainable(algorithm).suffix:
        written = "a mixed team's policy file (a zip of an ONNX policy per robot)"
    else:
        written = "an ONNX policy" if suffix == ".onnx" else "a zip policy"
    if Path(str(out)).suffix != suffix:
        raise ValueError(
            f"--out {out}: {algorithm.upper()} writes {written}: give a file name ending in "
            f"{suffix} (curve.json, curve.png, train.json and results.json go beside it)"
        )
    return check_output_path(out, "--out")


TRAINING_RECORDS = ("train.json", "curve.json", "results.json")  # written beside a policy


class StoppedTrainingError(ValueError):
    """A training's folder holds a stopped training (`bbbench.training.benchmarl.segments`)
    of another kind than the one asked for: said before anything is trained."""


def check_fresh(out: str | Path, log_dir: str | Path | None = None) -> None:
    """`ValueError` if a training to `out` (its logs in `log_dir`, default `out`'s folder)
    would overwrite a policy or another training's records: a training never does."""
    out = Path(out)
    if out.exists():
        raise ValueError(
            f"--out {out}: a file is there already, and a training never overwrites one: "
            f"give another name, or move it away first"
        )
    logs = Path(log_dir) if log_dir is not None else out.parent
    taken = [name for name in TRAINING_RECORDS if (logs / name).exists()]
    if taken:
        raise ValueError(
            f"{logs}/ holds another training's records ({', '.join(taken)}): give each "
            f"training a folder of its own (--out in a new folder, or --log)"
        )


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


@dataclasses.dataclass(frozen=True)
class Schedule:
    """How a training of a recipe runs, checked, for either route: its budget and batch
    (`check_collection`), its envs (worlds), where the policy and the logs go, and how
    often it evaluates."""

    budget: int
    batch: int
    n_envs: int
    out: Path
    log_dir: Path
    eval_freq: int


def schedule(
    plan,
    algorithm: str,
    tasks: Sequence[str],
    out: str | Path,
    n_envs: int | None,
    workers: int | None,
    steps: int | None,
    log_dir: str | Path | None,
    eval_freq: int | None,
) -> Schedule:
    """The `Schedule` of a training of `plan`: `n_envs` and the budget default to the
    recipe's, the logs to the policy's folder (made), the evaluations to a tenth of the
    budget and at least a batch. `ValueError` for what cannot be trained or written."""
    budget, batch, _ = check_collection(plan, tasks, n_envs, workers, steps)
    out = check_policy_path(algorithm, out, tasks)
    log_dir = Path(log_dir) if log_dir is not None else out.parent
    log_dir.mkdir(parents=True, exist_ok=True)
    check_output_path(log_dir / "curve.json", "--log")
    eval_freq = max(eval_freq or budget // 10, batch)
    return Schedule(budget, batch, n_envs or plan.n_envs, out, log_dir, eval_freq)

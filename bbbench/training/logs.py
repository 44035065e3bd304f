"""What a training leaves beside its policy, whichever trainer ran it (stable-baselines3
in `bbbench.training.sb3`, BenchMARL in `bbbench.training.benchmarl`): the `Trained`
record, and curve.json, curve.png, train.json and results.json written at once; and a
run's episodes on a task, from its own results.json or, once it is on a leaderboard
(which keeps the same episodes, and the run's copy is dropped), the board's."""

from __future__ import annotations

import dataclasses
import io
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from bbbench.evaluation import stats
from bbbench.evaluation.play import PlayedEpisode
from bbbench.evaluation.results import dumps as results_text
from bbbench.evaluation.results import read as read_results
from bbbench.files import write_all_atomic


@dataclasses.dataclass(frozen=True)
class Trained:
    """What `train` did: the zip, the learning curve, the final results document."""

    out: Path
    log_dir: Path
    statistics: Path | None  # the VecNormalize statistics of a recipe with `normalize`
    curve: list[dict[str, float]]
    results: dict[str, Any]
    seconds: float
    recipe: Any  # the recipe it trained with
    kept: dict[str, float] | None = None  # the curve's point of the policy written

    def __post_init__(self) -> None:
        if self.kept is None:  # stable-baselines3's rule: the best point's policy
            object.__setattr__(self, "kept", max(self.curve, key=lambda point: point["mean"]))


def curve_point(played: list[PlayedEpisode], began: float, **steps: int) -> dict[str, float]:
    """A point of the learning curve: `steps` (the trainer's counts, `steps=` first), the
    wall time since `began` (`time.perf_counter()`), the mean return, IQM and mean
    length of the episodes `played` on the training seeds, and each episode's return (in
    the order of the seeds: curves over several training seeds pool them)."""
    returns = np.array([episode.episode_return for episode in played])
    return {
        **{name: int(count) for name, count in steps.items()},
        "wall_time_s": round(time.perf_counter() - began, 2),
        "mean": float(returns.mean()),
        "iqm": stats.iqm(returns),
        "mean_length": float(np.mean([episode.length for episode in played])),
        "returns": [float(value) for value in returns],
    }


def write_logs(log_dir: Path, curve, tasks, algorithm, record, results) -> None:
    """curve.json, curve.png, train.json and results.json, all at once."""
    write_all_atomic(
        {
            log_dir / "curve.json": dumps({"points": curve}),
            log_dir / "curve.png": curve_png(curve, tasks, algorithm),
            log_dir / "train.json": dumps(record),
            log_dir / "results.json": results_text(results).encode(),
        }
    )


def run_episodes(log_dir: Path, task_id: str, board: Path) -> list[dict[str, Any]] | None:
    """The episodes of the run trained in `log_dir` on `task_id`'s evaluation seeds: its
    own results.json's, or the board's `results/<run>.json` (the run's folder name) when
    the run's results do not hold the task (dropped once the board held them, or a later
    version of the task); None when neither does."""
    for path in (log_dir / "results.json", board / "results" / f"{log_dir.name}.json"):
        if path.is_file():
            for block in read_results(path)["tasks"]:
                if block["task"] == task_id:
                    return block["episodes"]
    return None


def dumps(document: dict[str, Any]) -> bytes:
    return (json.dumps(document, indent=2) + "\n").encode()


def curve_png(curve: list[dict[str, float]], tasks: list[str], algorithm: str) -> bytes:
    from matplotlib.figure import Figure  # lazy: matplotlib, for the curve only

    figure = Figure(figsize=(6.0, 3.4), layout="constrained")
    axes = figure.add_subplot()
    steps = [point["steps"] for point in curve]
    axes.plot(steps, [point["mean"] for point in curve], marker="o", label="mean return")
    axes.plot(steps, [point["iqm"] for point in curve], marker=".", label="IQM")
    axes.set_xlabel("environment steps")
    axes.set_ylabel("return on training seeds")
    names = ", ".join(task.removeprefix("bbbench/") for task in tasks)
    axes.set_title(f"{algorithm.upper()} on {names}", fontsize=9)
    axes.grid(alpha=0.3)
    axes.legend(frameon=False)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100, metadata={"Software": None})
    return buffer.getvalue()

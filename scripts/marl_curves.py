"""The MARL campaign's sample-efficiency curves (docs/notebook.md, "The field's budget"):
for each task, the IQM of the normalized return over every seed's training episodes at
each evaluation point, with its 95% stratified-bootstrap interval (the seeds are the
strata: rliable's and marl-eval's curve), IPPO and MAPPO, and the classical
controller's return on the same training seeds as a line.

    python scripts/marl_curves.py [--root baselines] [--out docs/images]
                                  [--marl-eval curves.json] [--cells CELL ...]

Reads each run's `baselines/<algo>-<task>-3m-s<seed>/curve.json` (every point keeps
each training episode's return); seeds not trained yet are left out, and a task with
no run is skipped. Writes `marl-curves-<task>.svg` per task and prints, per task and
method, the points' steps, IQM and interval as a Markdown table, then each curve by its
points at every `MILESTONE` world steps and at its end, with where the end's interval lies
against the controller's line (a curve is described by its points: no line is fitted
through a few noisy ones, nor extended past the budget). `--marl-eval` also
writes the curves as marl-eval's raw data (one run per seed, one logging step per
evaluation point), for its own `sample_efficiency_curves`.
"""

from __future__ import annotations

import argparse
import io
import json
import sys
from pathlib import Path

import numpy as np

from bbbench.evaluation import stats
from bbbench.evaluation.episodes import LockstepPlayer
from bbbench.evaluation.marl_eval import ENVIRONMENT
from bbbench.evaluation.results import normalized
from bbbench.files import write_atomic
from bbbench.policies import classical_controller, load_policy
from bbbench.tasks.suite import spec
from bbbench.training import evaluation_seeds
from bbbench.training.logs import run_episodes

sys.path.insert(0, str(Path(__file__).parent))
from board_runs import SEEDS, cell_slug, short

TASKS = (
    "bbbench/MultiBalance-v1",
    "bbbench/MultiBumps-v1",
    "bbbench/BeamCarry-v0",
    "bbbench/BeamCarryBumps-v0",
    "bbbench/Convoy-v0",
)
METHODS = ("ippo", "mappo")
BOARD = Path(__file__).resolve().parents[1] / "leaderboards"
MILESTONE = 1_000_000  # world steps: the curve's points the end-of-curve table quotes


def cell_runs(root: Path, stem: str) -> dict[int, list[dict]]:
    """Each trained seed's curve points, from `<root>/<stem>-s<seed>/curve.json`."""
    runs = {}
    for seed in SEEDS:
        path = root / f"{stem}-s{seed}" / "curve.json"
        if path.is_file():
            runs[seed] = json.loads(path.read_text())["points"]
    return runs


def curve(task_id: str, runs: dict[int, list[dict]]) -> list[dict]:
    """At each evaluation point every seed reached: the steps, the IQM of the normalized
    returns of every seed's episodes, and its 95% stratified-bootstrap interval."""
    task = spec(task_id)
    points = []
    for index in range(min(len(points) for points in runs.values())):
        strata = [
            np.array([normalized(value, task) for value in run[index]["returns"]])
            for run in runs.values()
        ]
        low, high = stats.stratified_bootstrap_ci(strata, stats.iqm)
        steps = max(run[index]["steps"] for run in runs.values())
        points.append({"steps": steps, "iqm": stats.iqm(np.concatenate(strata)), "ci": (low, high)})
    return points


def milestones(points: list[dict], every: int = MILESTONE) -> list[dict]:
    """The curve's points nearest each whole `every` world steps before its end, and its
    last point: what the table quotes of a curve."""
    last = points[-1]
    chosen: list[dict] = []
    for mark in range(every, last["steps"] - every // 2, every):
        nearest = min(points, key=lambda point, mark=mark: abs(point["steps"] - mark))
        if nearest is not last and nearest not in chosen:
            chosen.append(nearest)
    return [*chosen, last]


def against_line(point: dict, line: float) -> str:
    """Where a point's interval lies against the controller's line."""
    low, high = point["ci"]
    if low > line:
        return "above it"
    if high < line:
        return "below it"
    return "level: its interval holds the line"


def controller_line(task_id: str) -> float:
    """The classical controller's normalized return on the curve's training seeds,
    aggregated as the curve is: the IQM of its episodes."""
    player = LockstepPlayer(
        actors={task_id: load_policy(classical_controller(task_id)).actor(task_id)},
        action_mode="discrete",
        sampled=False,
    )
    played = player.play(task_id, evaluation_seeds(task_id))
    player.close()
    return float(stats.iqm(np.array([normalized(e.episode_return, spec(task_id)) for e in played])))


def figure(task_id: str, curves: dict[str, list[dict]], line: float) -> bytes:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams["svg.hashsalt"] = "bbbench"
    fig, axes = plt.subplots(figsize=(6, 3.6))
    for method, points in curves.items():
        steps = [point["steps"] / 1e6 for point in points]
        axes.plot(steps, [point["iqm"] for point in points], marker="o", label=method.upper())
        axes.fill_between(
            steps, [p["ci"][0] for p in points], [p["ci"][1] for p in points], alpha=0.25
        )
    controller = classical_controller(task_id)
    axes.axhline(line, color="black", linestyle="--", label=f"{controller} controller")
    axes.set_xlabel("world steps (millions)")
    axes.set_ylabel("normalized return (IQM, 95% CI)")
    axes.set_title(f"{short(task_id)}: training seeds")
    axes.legend(loc="lower right")
    fig.tight_layout()
    out = io.BytesIO()
    fig.savefig(out, format="svg", metadata={"Date": None})
    plt.close(fig)
    return out.getvalue()


def final_returns(
    root: Path, stem: str, seed: int, task_id: str, board: Path = BOARD
) -> list[float] | None:
    """The kept policy's returns on the task's evaluation seeds (its results.json, or
    the board's once the board holds them)."""
    played = run_episodes(root / f"{stem}-s{seed}", task_id, board)
    return None if played is None else [episode["return"] for episode in played]


def marl_eval_curves(runs: dict[int, list[dict]], finals: dict[int, list[float] | None]) -> dict:
    """One method's curves on one task as marl-eval's raw data: a logging step per
    evaluation point, and as `absolute_metrics` the kept policy's returns on the
    evaluation seeds (the last point's, for a run without its results)."""
    data = {}
    for seed, points in runs.items():
        steps = {
            f"step_{index}": {"step_count": point["steps"], "return": point["returns"]}
            for index, point in enumerate(points)
        }
        final = finals.get(seed) or points[-1]["returns"]
        data[f"run_{seed}"] = {**steps, "absolute_metrics": {"return": final}}
    return data


def parse_cell(
    parser: argparse.ArgumentParser, root: Path, text: str
) -> tuple[tuple[str, str], str]:
    """`METHOD=STEM TASK` as ((task, method), stem), or the parser's one-line error."""
    named, _, task = text.partition(" ")
    method, _, stem = named.partition("=")
    if not (method and stem and task):
        parser.error(
            f"--cells {text!r}: expected METHOD=STEM TASK, "
            "e.g. 'ippo=ippo-swap-v0-3m bbbench/Swap-v0'"
        )
    try:
        classical_controller(task)
    except ValueError as error:
        parser.error(f"--cells {text!r}: {error}")
    if not cell_runs(root, stem):
        expected = ", ".join(str(root / f"{stem}-s{seed}" / "curve.json") for seed in SEEDS)
        parser.error(f"--cells {text!r}: no run found; expected one of {expected}")
    return (task, method), stem


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=Path("baselines"))
    parser.add_argument("--out", type=Path, default=Path("docs/images"))
    parser.add_argument("--marl-eval", type=Path, help="also write the curves for marl-eval")
    parser.add_argument(
        "--cells",
        nargs="*",
        help="METHOD=STEM TASK: other runs' folders (<STEM>-s<seed>) instead of the campaign's",
    )
    args = parser.parse_args()
    if not args.out.is_dir():
        parser.error(f"--out {args.out}: no such directory; give an existing one")
    cells = {(task, method): cell_slug(method, task) for task in TASKS for method in METHODS}
    if args.cells:
        cells = dict(parse_cell(parser, args.root, text) for text in args.cells)
    data: dict = {}
    for task_id in dict.fromkeys(task for task, _ in cells):
        curves = {}
        for (task, method), stem in cells.items():
            runs = cell_runs(args.root, stem) if task == task_id else {}
            if runs:
                curves[method] = curve(task_id, runs)
                name = short(task_id)
                finals = {seed: final_returns(args.root, stem, seed, task) for seed in runs}
                data.setdefault(name, {})[method.upper()] = marl_eval_curves(runs, finals)
        if not curves:
            continue
        line = controller_line(task_id)
        target = args.out / f"marl-curves-{short(task_id).lower()}.svg"
        write_atomic(target, figure(task_id, curves, line))
        controller = classical_controller(task_id)
        print(f"\n{task_id} ({controller} on the same seeds: {line:.3f}), {target}\n")
        print("| method | world steps | IQM [95% CI] |")
        print("|---|---:|---|")
        for method, points in curves.items():
            for point in points:
                low, high = point["ci"]
                print(
                    f"| {method.upper()} | {point['steps']:,} | "
                    f"{point['iqm']:.3f} [{low:.3f}, {high:.3f}] |"
                )
        print(
            f"\n| method | IQM near every {MILESTONE / 1e6:g}M world steps, and at the end "
            f"[95% CI] | the end, against {controller}'s {line:.3f} |"
        )
        print("|---|---|---|")
        for method, points in curves.items():
            *before, end = milestones(points)
            shown = [f"{p['iqm']:.3f} ({p['steps'] / 1e6:.1f}M)" for p in before]
            low, high = end["ci"]
            shown.append(f"{end['iqm']:.3f} [{low:.3f}, {high:.3f}] ({end['steps'] / 1e6:.1f}M)")
            print(f"| {method.upper()} | {', '.join(shown)} | {against_line(end, line)} |")
    if args.marl_eval is not None:
        args.marl_eval.write_text(json.dumps({ENVIRONMENT: data}, indent=1) + "\n")


if __name__ == "__main__":
    main()

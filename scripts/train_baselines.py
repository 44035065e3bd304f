"""Train the leaderboard's reference baselines with `bbbench train`, and add each to the
leaderboard with `bbbench leaderboard add` as it finishes.

    python scripts/train_baselines.py [--parallel 2] [--only ppo-flatbalance-v1-s0 ...] [--list]
                                      [--train-only] [--add-trained] [--table [legged]]
    python scripts/train_baselines.py --campaign [--only ippo-multibalance-v1-3m ...]

Each run writes `baselines/<slug>/` (curve.json, curve.png, train.json, results.json,
the command's output; git keeps neither curve.png, drawn from curve.json, nor, once the
board holds the same episodes, results.json); its policy goes into its method's folder on the board,
`leaderboards/submissions/<method>/runs/s<seed>/` (the slug is `<method>-s<seed>`), with a
run.json that records the exact command, the recipe and budget in world steps, the wall
time and the machine. Runs already on the board are skipped. Training takes most of a 2-core
machine for hours: run it in the background.

`--campaign` trains the MARL baselines at the field's budget (the shipped IPPO and MAPPO
recipes: 3M world steps), one cell (algorithm, task) at a time, its missing seeds one
after another (`bbbench train ... --seed S`, its worlds in the recipe's worker processes,
the same bytes as any run of the seed); each seed goes on the board as a run of the
method `<algo>-<task>-3m`. A seed stopped in a recipe with segments resumes where it was
when it is asked for again.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from bbbench.evaluation.results import read
from bbbench.leaderboard.board import is_profile
from bbbench.policies import classical_controller
from bbbench.policies.sb3.vecnormalize import find_rl_zoo_statistics
from bbbench.tasks.suite import scored_version, spec
from bbbench.tasks.tracks import track_of
from bbbench.training import MARL_TRAINABLE
from bbbench.training.beside import described
from bbbench.training.checks import policy_suffix

sys.path.insert(0, str(Path(__file__).parent))
from board_runs import (
    SEEDS,
    VARIANTS,
    board_lock,
    cell_slug,
    drop_repeated_results,
    method_slug,
    on_board,
    short,
    world_steps,
)

LATEST_SINGLE = (
    "bbbench/FlatBalance-v1",
    "bbbench/VelocityTracking-v1",
    "bbbench/NoisySensors-v1",
    "bbbench/Bumps-v2",
    "bbbench/Obstacles-v2",
    "bbbench/Slopes-v2",
)
# Tasks published after the generalist was trained: one PPO per seed, not in its mix.
ADDED_SINGLE = ("bbbench/PushRecovery-v0",)
LATEST_MULTI = ("bbbench/MultiBalance-v1", "bbbench/MultiBumps-v1")
NOISY_MULTI = ("bbbench/MultiNoisySensors-v0",)  # issue 67: the campaign's, at 3M only
# The wheel-legged robot's tasks: PPO on three seeds, and SAC, each.
LEGGED = (
    "bbbench/LeggedFlatBalance-v0",
    "bbbench/LeggedVelocityTracking-v0",
    "bbbench/LeggedBumps-v0",
    "bbbench/LeggedObstacles-v0",
)
# The team tasks: PPO shared by every bot of the column, three seeds each.
TEAMS = ("bbbench/BeamCarry-v0", "bbbench/BeamCarryBumps-v0", "bbbench/Convoy-v0")
# The steering robot's tasks (issue 52): PPO on the single-bot ones, three seeds each;
# IPPO and MAPPO on the multi-bot and team ones, at the field's budget (the campaign).
STEERING_SINGLE = ("bbbench/SteerTracking-v0", "bbbench/Waypoints-v0", "bbbench/WaypointsBumps-v0")
STEERING_MULTI = ("bbbench/Swap-v0", "bbbench/ConvoyTurns-v0", "bbbench/Rendezvous-v0")
# The mixed team (issue 67): IPPO and MAPPO, a policy per robot, into one team file.
MIXED_TEAMS = ("bbbench/MixedBeamCarry-v0", "bbbench/MixedBeamCarryBumps-v0")
# The MARL baselines: BenchMARL's MAPPO and IPPO (fallen bots masked, the neighbour
# encoder as actor), three seeds each, on every multi-bot and team task; ONNX policies.
MARL = ("mappo", "ippo")


def runs() -> list[dict]:
    """Every baseline, in the order they are trained: the generalist and one seed of
    everything first."""
    ppo = [{"tasks": [task], "algo": "ppo"} for task in (*LATEST_SINGLE, *ADDED_SINGLE)]
    multi = [{"tasks": [task], "algo": "ppo"} for task in LATEST_MULTI]
    generalist = {"tasks": list(LATEST_SINGLE), "algo": "ppo", "generalist": True}
    plan = [
        {**generalist, "seed": 0},
        *({**run, "seed": 0} for run in ppo),
        *({**run, "seed": 0} for run in multi),
        *({**run, "seed": seed} for seed in SEEDS[1:] for run in ppo),
        *({"tasks": [task], "algo": "ppo", "seed": seed} for seed in SEEDS for task in LEGGED),
        *({"tasks": [task], "algo": "sac", "seed": 0} for task in LEGGED),
        *({"tasks": [task], "algo": "ppo", "seed": seed} for seed in SEEDS for task in TEAMS),
        # A second family on the single-bot track: SAC, seed 0, continuous actions.
        *({"tasks": [task], "algo": "sac", "seed": 0} for task in (*LATEST_SINGLE, *ADDED_SINGLE)),
        # A method is its seeds (issue 65): the second and third seed of the runs above
        # that had one.
        *(
            {"tasks": [task], "algo": "sac", "seed": seed}
            for seed in SEEDS[1:]
            for task in (*LATEST_SINGLE, *ADDED_SINGLE, *LEGGED)
        ),
        *({**run, "seed": seed} for seed in SEEDS[1:] for run in multi),
        *({**generalist, "seed": seed} for seed in SEEDS[1:]),
        *(
            {"tasks": [task], "algo": algo, "seed": seed}
            for seed in SEEDS
            for algo in MARL
            for task in (*LATEST_MULTI, *TEAMS)
        ),
        *(
            {"tasks": [task], "algo": "ppo", "seed": seed}
            for seed in SEEDS
            for task in STEERING_SINGLE
        ),
    ]
    for run in plan:
        name = "generalist-v1" if run.get("generalist") else short(run["tasks"][0]).lower()
        run["slug"] = f"{run['algo']}-{name}-s{run['seed']}"
    return plan


def campaign() -> list[dict]:
    """The MARL cells at the field's budget, IPPO first: (algorithm, task), its seeds;
    then the cells of a recipe of their own (`VARIANTS`: the messages muted, continuous
    actions), each its own recipe file and method name."""
    cells = [
        {
            "cell": cell_slug(algo, task),
            "algo": algo,
            "tasks": [task],
            "seeds": SEEDS,
        }
        for algo in ("ippo", "mappo")
        for task in (*LATEST_MULTI, *NOISY_MULTI, *TEAMS, *STEERING_MULTI, *MIXED_TEAMS)
    ]
    return [*cells, *VARIANTS]


def policy_name(run: dict) -> str:
    """The policy file a run writes: a zip (stable-baselines3), ONNX (BenchMARL), a team
    file, a zip, on a mixed team (`policy_suffix`)."""
    return f"policy{policy_suffix(run['algo'], run['tasks'])}"


def command(run: dict, folder: Path) -> list[str]:
    return [
        "bbbench", "train", *run["tasks"], "--algo", run["algo"], "--seed", str(run["seed"]),
        "--out", str(folder / policy_name(run)),
    ]  # fmt: skip


def _add(
    run: dict,
    folder: Path,
    board: Path,
    minutes: float,
    side_by_side: int | str,
    argv: list[str] | None = None,
    beside: str | None = None,
) -> str:
    """`bbbench leaderboard add` of a finished run, with what it took (`argv`: the
    command that trained it, default `command(run, folder)`)."""
    argv = argv or command(run, folder)
    record = json.loads((folder / "train.json").read_text())
    points = len(json.loads((folder / "curve.json").read_text())["points"])
    names = "a mix of the single-bot tasks" if run.get("generalist") else run["tasks"][0]
    policy = folder / policy_name(run)
    method = method_slug(run)
    recipe = run.get("recipe") or f"bbbench/training/recipes/{run['algo']}.yml"
    shipped = "the shipped" if "recipe" not in run else "the"
    add = [
        "bbbench", "leaderboard", "add", str(policy), "--root", str(board), "--slug", method,
        "--seed", str(run["seed"]),
        "--world-steps", str(world_steps(record)), "--trained-on", *record["tasks"],
        "--recipe", recipe,
        "--wall-time", f"{minutes:.0f} min, with the periodic evaluations",
        "--hardware", f"{os.cpu_count()} CPU cores ({platform.machine()}), no GPU, "
        + (described(record.get("trainings_beside")) or _asked(side_by_side))
        + (f", beside {beside}" if beside else ""),
        "--command", " ".join([*argv[:-2], "--out", policy.name]),
        "--run-notes", f"Trained on {names} with {shipped} {run['algo']} recipe ({recipe}): "
        + (f"the last of {points} evaluations" if run["algo"] in MARL_TRAINABLE
           else f"the best of {points} evaluations")
        + f" on training seeds. Curve and logs: baselines/{run['slug']}/.",
    ]  # fmt: skip
    if not (board / "submissions" / method).exists():  # a new method: its own fields
        add += [
            "--name", run.get("name") or f"{run['algo'].upper()} {_display(run)}",
            "--algorithm", run["algo"].upper(), "--author", "bbbench maintainers",
            "--licence", "MIT",
            "--track", track_of(spec(record["tasks"][0])).name,
            "--notes", f"Trained on {names} with {shipped} {run['algo']} recipe ({recipe}). "
            f"Curves and logs: baselines/{method}-s<seed>/.",
        ]  # fmt: skip
    # A recipe with `normalize` writes statistics where rl-zoo3 does; eval finds them so.
    statistics = find_rl_zoo_statistics(policy) if policy.suffix == ".zip" else None
    if statistics is not None:
        add += ["--vecnormalize", str(statistics)]
    subprocess.run(add, check=True, stdout=subprocess.DEVNULL)
    drop_repeated_results(folder, board)
    policy.unlink()  # the board keeps it, in submissions/<method>/runs/s<seed>/
    if statistics is not None:
        statistics.unlink()
        statistics.parent.rmdir()
    return f"{run['slug']}: {minutes:.1f} min, on the board"


def _asked(side_by_side: int | str) -> str:
    """Trainings side by side as the script ran them, for records made before trainings
    counted their neighbours (`trainings_beside` in train.json)."""
    return f"{side_by_side} trainings side by side" if side_by_side != 1 else "one training"


def table(root: Path, board: Path, which: str = "all") -> str:
    """The Markdown table of the runs on the board: steps, each seed's training wall
    time and its normalized score on its task's evaluation seeds, and PD's (`which`:
    "all", or "legged" for the wheel-legged robot's rows alone)."""
    stored = [p for p in sorted((board / "results").glob("*.json")) if not is_profile(p.name)]
    results = {path.stem: read(path) for path in stored}

    def score(slug: str, task_id: str) -> float | None:
        for block in results.get(slug, {}).get("tasks", []):
            if block["task"] == task_id:
                return block["aggregate"]["normalized_score"]
        return None

    lines = [
        "| task | steps | training wall time, by seed | normalized, by seed | classical |",
        "|---|---:|---:|---|---:|",
    ]
    plan = runs()
    legged = [f"{task} {algo}" for algo in ("ppo", "sac") for task in LEGGED]
    rows = [*LATEST_SINGLE, *ADDED_SINGLE, *LATEST_MULTI, *TEAMS, "generalist", *legged]
    rows += [f"{task} sac" for task in (*LATEST_SINGLE, *ADDED_SINGLE)]
    rows += [f"{task} {algo}" for algo in MARL for task in (*LATEST_MULTI, *TEAMS)]
    rows += [*STEERING_SINGLE, *(f"{task} {algo}" for algo in MARL for task in STEERING_MULTI)]
    rows += [f"{task} {algo}" for algo in MARL for task in MIXED_TEAMS]
    if which == "legged":
        rows = legged
    for row in rows:
        task_id, _, algo = row.partition(" ")
        plan_here = [run for run in plan if _row(run) == task_id]
        if algo in MARL:  # the campaign's cell at the field's budget, once it is on the board
            cell = cell_slug(algo, task_id)
            campaign = [{"slug": f"{cell}-s{seed}", "algo": algo} for seed in SEEDS]
            if any(run["slug"] in results for run in campaign):
                plan_here = campaign
        done = [
            run for run in plan_here if run["algo"] == (algo or "ppo") and run["slug"] in results
        ]
        if not done:
            continue
        records = [json.loads((root / run["slug"] / "train.json").read_text()) for run in done]
        minutes = " / ".join(f"{record['wall_time_s'] / 60:.1f}" for record in records)
        if task_id == "generalist":
            scores = "; ".join(
                " / ".join(f"{score(run['slug'], task):.3f}" for task in LATEST_SINGLE)
                for run in done
            )
            name = "generalist (by task: the six before PushRecovery, in order; seeds apart by ;)"
            pd = ""
        else:  # scored on the task's latest version, which the board plays
            on, trained_on = scored_version(task_id)
            scores = " / ".join(f"{score(run['slug'], on):.3f}" for run in done)
            classical = classical_controller(on)
            name = short(on) + (f" ({algo.upper()})" if algo else "")
            name += trained_on
            pd = f"{score(classical, on):.3f}"
        steps = world_steps(records[0])  # world steps, the board's unit
        budget = f"{steps / 1e6:.3g}M" if steps >= 1e6 else f"{steps / 1e3:.3g}k"
        lines.append(f"| {name} | {budget} | {minutes} min | {scores} | {pd} |")
    return "\n".join(lines)


def _row(run: dict) -> str:
    """The table row a run belongs to: its task, or "generalist"."""
    return "generalist" if run.get("generalist") else run["tasks"][0]


def _display(run: dict) -> str:
    if run.get("generalist"):
        return "generalist"
    return short(run["tasks"][0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parallel", type=int, default=2)
    parser.add_argument("--only", nargs="*", help="slugs to train (default: every missing one)")
    parser.add_argument("--list", action="store_true", help="print the plan and exit")
    parser.add_argument(
        "--train-only",
        action="store_true",
        help="train, and leave each policy in baselines/<slug>/ for a later --add-trained",
    )
    parser.add_argument(
        "--add-trained",
        action="store_true",
        help="add the runs --train-only left in baselines/ to the board, one by one",
    )
    parser.add_argument(
        "--table",
        nargs="?",
        const="all",
        choices=("all", "legged"),
        help="print the Markdown table of the runs on the board (legged: the wheel-legged "
        "robot's rows)",
    )
    parser.add_argument(
        "--campaign",
        action="store_true",
        help="the MARL cells at the field's budget, each cell's seeds as Ray tasks",
    )
    parser.add_argument(
        "--seeds",
        type=lambda text: [int(seed) for seed in text.split(",")],
        help="with --campaign: these seeds of each cell only (default 0,1,2)",
    )
    parser.add_argument(
        "--beside",
        help="with --add-trained: what else ran on the machine during the trainings, in "
        "words (their records count only other trainings)",
    )
    parser.add_argument("--root", type=Path, default=Path("baselines"))
    parser.add_argument("--board", type=Path, default=Path("leaderboards"))
    args = parser.parse_args()
    if args.campaign:
        for cell in campaign():
            if not args.only or cell["cell"] in args.only:
                if args.list:
                    print(cell["cell"], cell["seeds"])
                else:
                    _train_cell(cell, args)
        return
    plan = [run for run in runs() if not args.only or run["slug"] in args.only]
    missing = [run for run in plan if not on_board(args.board, run)]
    args.plan = missing
    if args.table:
        print(table(args.root, args.board, args.table))
        return
    if args.list:
        for run in plan:
            print(run["slug"], "" if run in missing else "(on the board)")
        return
    if args.add_trained:
        for run in missing:
            folder = args.root / run["slug"]
            if (folder / policy_name(run)).exists():
                record = json.loads((folder / "train.json").read_text())
                side_by_side = record.get("side_by_side", 1)
                minutes = record["wall_time_s"] / 60
                print(_add(run, folder, args.board, minutes, side_by_side, beside=args.beside))
        return
    with ThreadPoolExecutor(args.parallel) as pool:
        for line in pool.map(lambda run: _train_and_add(run, args), missing):
            print(line, flush=True)


def _train_cell(cell: dict, args: argparse.Namespace) -> None:
    """A campaign cell: its missing seeds one after another, each its own `bbbench train
    --seed` process in a folder of its own, kept until it ends (a recipe in segments
    resumes there when the seed is asked for again: `bbbench.training.benchmarl.segments`),
    then on the board in place of its 300k entry."""
    seeds = [
        s
        for s in (args.seeds or cell["seeds"])
        if not on_board(args.board, {"slug": f"{cell['cell']}-s{s}", "seed": s})
    ]
    if not seeds:
        return
    argv = ["bbbench", "train", *cell["tasks"], "--algo", cell["algo"]]
    if "recipe" in cell:
        argv += ["--recipe", cell["recipe"]]
    began = time.perf_counter()
    # One seed at a time, its worlds in the recipe's worker processes: two MAPPO seeds side
    # by side (one process each) took 1,425 s to 300k world steps where one alone took
    # 221 s, their updates' torch threads (two each) fighting for two cores (the notebook).
    for seed in seeds:
        code = _seed(argv, args.root, cell, seed)
        slug = f"{cell['cell']}-s{seed}"
        folder = args.root / f"{cell['cell']}-training-s{seed}"
        if code:
            print(f"{slug}: exit {code} (resumes if asked for again), see {folder}/train.log")
            continue
        # The cell's log keeps every run of it (seeds trained in several goes).
        with open(args.root / f"{cell['cell']}.log", "a") as whole:
            whole.write((folder / "train.log").read_text())
        (folder / "train.log").unlink()
        for scratch in folder.glob(".training-*"):  # left by a run that was stopped
            shutil.rmtree(scratch)
        target = args.root / slug
        folder.rename(target)
        run = {"tasks": cell["tasks"], "algo": cell["algo"], "seed": seed, "slug": slug}
        run.update({key: cell[key] for key in ("recipe", "name") if key in cell})
        record = json.loads((target / "train.json").read_text())
        # The seed's own command: `_add` records all of it but its last two (the --out).
        seeded = [*argv, "--seed", str(seed), "--out", "-"]
        minutes = record["wall_time_s"] / 60
        with board_lock(args.board):
            print(_add(run, target, args.board, minutes, 1, seeded), flush=True)
    print(f"{cell['cell']}: {(time.perf_counter() - began) / 60:.0f} min", flush=True)


def _seed(argv: list[str], root: Path, cell: dict, seed: int) -> int:
    """Seed `seed` of a campaign cell trained (or resumed) in
    `root/<cell>-training-s<seed>/`; its exit code, its output appended to train.log there."""
    folder = root / f"{cell['cell']}-training-s{seed}"
    folder.mkdir(parents=True, exist_ok=True)
    one = [*argv, "--seed", str(seed), "--out", str(folder / policy_name(cell))]
    with open(folder / "train.log", "a") as log:
        return subprocess.run(one, stdout=log, stderr=subprocess.STDOUT).returncode


def _train_and_add(run: dict, args: argparse.Namespace) -> str:
    folder = args.root / run["slug"]
    folder.mkdir(parents=True, exist_ok=True)
    began = time.perf_counter()
    with open(folder / "train.log", "w") as log:
        done = subprocess.run(command(run, folder), stdout=log, stderr=subprocess.STDOUT)
    if done.returncode:
        return f"{run['slug']}: training failed (exit {done.returncode}), see {folder}/train.log"
    side_by_side = min(args.parallel, len(args.plan))
    if args.train_only:
        record = json.loads((folder / "train.json").read_text())
        record["side_by_side"] = side_by_side
        (folder / "train.json").write_text(json.dumps(record, indent=2) + "\n")
        return f"{run['slug']}: trained in {(time.perf_counter() - began) / 60:.1f} min"
    with board_lock(args.board):  # `add` rebuilds the board: one run at a time
        minutes = (time.perf_counter() - began) / 60
        return _add(run, folder, args.board, minutes, side_by_side)


if __name__ == "__main__":
    sys.exit(main())

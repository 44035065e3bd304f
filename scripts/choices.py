"""The choices behind the shipped recipes, controller and tasks, made again on the tasks'
validation seeds (`TaskSpec.validation_seeds`), never on their evaluation seeds.

Each choice is data (`CHOICES`): the question, the value shipped, the candidates, and the
rule that picks one. Its record, `baselines/choices/<name>.json`, holds every candidate's
figures on the validation seeds, the value the rule picks, and whether that is the value
shipped. A recipe's candidates are trained first (seed 0, the shipped budget), each into
`baselines/choices/<name>/<candidate>/`; the shipped value's candidate is the board's own
seed-0 run of that recipe, trained with it. A trained candidate's folder keeps its recipe,
command log, curve and `train.json`; its policy stays out of git (the record names its
SHA-256: `--train` makes it again). docs/baselines.md's table of choices, and docs/tasks.md's
tables of the task calibrations, are generated from the records (scripts/choice_tables.py).

    python scripts/choices.py --list
    python scripts/choices.py --train slopes-gamma       # the candidates not trained yet
    python scripts/choices.py --evaluate slopes-gamma    # their record, on validation seeds
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
FOLDER = ROOT / "baselines" / "choices"
BOARD = ROOT / "leaderboards" / "submissions"
SPLIT = "validation"


@dataclasses.dataclass(frozen=True)
class Candidate:
    """One value a choice could take: `label` as the record shows it, `slug` for its files."""

    label: str
    slug: str
    value: Any  # a recipe's {key: value} override, a controller's keywords, a task's setting
    board_run: str | None = None  # the board's seed-0 run that already trained this value


@dataclasses.dataclass(frozen=True)
class Choice:
    name: str
    question: str
    kind: str  # "recipe" (trained, then scored), "controller" or "task" (scored only)
    tasks: tuple[str, ...]
    candidates: tuple[Candidate, ...]
    shipped: str  # the label of the value shipped
    rule: str  # in words, as the record and the docs state it
    algorithm: str = "ppo"
    was: str = ""  # what the choice was made on before


# The board's rule for a verdict, applied to a choice: one seed's (or one controller's)
# lead within the noise of its episodes changes nothing.
BEST = (
    "the best normalized score on the validation seeds, where P(it > shipped) has its "
    "interval above 0.5; else the value shipped stands"
)


def _ppo(task: str, label: str, slug: str, override: dict, board: str | None = None):
    return Candidate(label, slug, {"task": task, "override": override}, board)


def _learning_rate(task: str, question: str, shipped: str, other: str, was: str) -> Choice:
    """A wheel-legged task's PPO learning rate: `other` trained, against the board's own
    seed 0 at the rate shipped."""
    short = task.removeprefix("bbbench/").lower()
    name = short.removeprefix("legged").removesuffix("-v0")
    return Choice(
        name=f"legged-{'tracking' if name == 'velocitytracking' else name}-learning-rate",
        question=question,
        kind="recipe",
        tasks=(task,),
        candidates=(
            _ppo(task, other, f"lr-{other}", {"learning_rate": float(other)}),
            _ppo(task, shipped, f"lr-{shipped}", {}, f"ppo-{short}/s0"),
        ),
        shipped=shipped,
        rule=BEST,
        was=was,
    )


def _difficulty(task: str, ground: str, values, shipped: str, rule: str, was: str) -> Choice:
    """A task's calibration of its difficulty: its classical controller at each value."""
    short = task.removeprefix("bbbench/")
    return Choice(
        name=f"{short.rsplit('-v', 1)[0].lower()}-difficulty",
        question=f"{short}'s difficulty ({ground})",
        kind="task",
        tasks=(task,),
        candidates=tuple(
            Candidate(f"{value}", f"difficulty-{value}", {"difficulty": value}) for value in values
        ),
        shipped=shipped,
        rule=rule,
        was=was,
    )


BAND_RULE = "{} finishes 20-60% of the episodes (the calibration band{})"
# A task's difficulty calibrated against its classical controller: the task, its ground,
# the values played, the value shipped, the rule, and what it was first chosen on.
DIFFICULTIES = [
    (
        "bbbench/WaypointsBumps-v0",
        "hills 0.01 m + 0.30 m x difficulty",
        (0.75, 0.8, 0.85, 0.9, 0.95),
        "0.85",
        BAND_RULE.format("the steering law", ""),
        "pilots on training seeds 1000-1019, then the evaluation seeds: 31 of 100",
    ),
    (
        "bbbench/Bumps-v2",
        "hills 0.01 m + 0.10 m x difficulty",
        (0.5, 0.75, 0.9, 1.0),
        "0.9",
        BAND_RULE.format("PD", " of the terrain"),
        "the evaluation seeds (on -v1, the same episodes): PD finished 52%, 37% and 23% at "
        "0.75, 0.9 and 1",
    ),
    (
        "bbbench/Obstacles-v2",
        "boxes, steps and gaps",
        (0.25, 0.5, 0.75, 1.0),
        "0.5",
        BAND_RULE.format("PD", " of the terrain"),
        "the evaluation seeds (on -v1, the same episodes): PD finished 68%, 36% and 20% at "
        "0.25, 0.5 and 0.75",
    ),
    (
        "bbbench/Slopes-v2",
        "ramps up to 0.5 rad x difficulty",
        (0.5, 0.7, 0.9, 1.0),
        "0.9",
        BAND_RULE.format("PD", " of the terrain"),
        "the evaluation seeds (on -v1, the same episodes): PD finished 87%, 55% and 38% at "
        "0.5, 0.9 and 1",
    ),
    (
        "bbbench/LeggedBumps-v0",
        "hills 0.01 m + 0.25 m x difficulty",
        (0.75, 0.8, 0.85, 0.9, 0.95),
        "0.85",
        BAND_RULE.format("the legged controller", ""),
        "the evaluation seeds: 72, 63 and 48 of 100 at 0.75, 0.8 and 0.85",
    ),
    (
        "bbbench/LeggedObstacles-v0",
        "Obstacles-v2's course",
        (0.7, 0.75, 0.8, 0.85, 0.9),
        "0.8",
        BAND_RULE.format("the legged controller", ""),
        "the evaluation seeds: 96 of 100 at 0.5 (Obstacles-v2's), 47 at 0.8",
    ),
]


CHOICES: dict[str, Choice] = {
    choice.name: choice
    for choice in [
        Choice(
            name="slopes-gamma",
            question="Slopes-v2's PPO gamma",
            kind="recipe",
            tasks=("bbbench/Slopes-v2",),
            candidates=(
                _ppo("bbbench/Slopes-v2", "gamma 0.995", "gamma-0.995", {"gamma": 0.995}),
                _ppo("bbbench/Slopes-v2", "gamma 0.999", "gamma-0.999", {}, "ppo-slopes-v2/s0"),
            ),
            shipped="gamma 0.999",
            rule=BEST,
            was="the evaluation seeds: 0.334 at 0.995, 0.359 at 0.999",
        ),
        Choice(
            name="team-learning-rate",
            question="the team tasks' PPO learning rate and gamma (BeamCarry-v0, 1M bot-steps)",
            kind="recipe",
            tasks=("bbbench/BeamCarry-v0",),
            candidates=tuple(
                _ppo("bbbench/BeamCarry-v0", label, slug, override, board)
                for label, slug, override, board in [
                    ("3e-4, gamma 0.99", "lr-3e-4-gamma-0.99", {"learning_rate": 3e-4}, None),
                    (
                        "3e-4, gamma 0.995",
                        "lr-3e-4-gamma-0.995",
                        {"learning_rate": 3e-4, "gamma": 0.995},
                        None,
                    ),
                    ("1e-4, gamma 0.995", "lr-1e-4-gamma-0.995", {"gamma": 0.995}, None),
                    ("1e-4, gamma 0.99", "lr-1e-4-gamma-0.99", {}, "ppo-beamcarry-v0/s0"),
                ]
            ),
            shipped="1e-4, gamma 0.99",
            rule=BEST,
            was="the evaluation seeds, at 2M bot-steps: 0.240, 0.221, 0.251, 0.308",
        ),
        _learning_rate(
            "bbbench/LeggedBumps-v0",
            "LeggedBumps-v0's PPO learning rate",
            shipped="1e-4",
            other="3e-4",
            was="the evaluation seeds: 0.284 at 3e-4, 0.422 at 1e-4",
        ),
        _learning_rate(
            "bbbench/LeggedVelocityTracking-v0",
            "LeggedVelocityTracking-v0's PPO learning rate (2M steps)",
            shipped="1e-4",
            other="3e-4",
            was="the evaluation seeds: 0.157 at 3e-4 and 1M steps, 0.538 at 1e-4 and 2M",
        ),
        _learning_rate(
            "bbbench/LeggedObstacles-v0",
            "LeggedObstacles-v0's PPO learning rate",
            shipped="3e-4",
            other="1e-4",
            was="not tried: 1e-4 was not trained on this task",
        ),
        Choice(
            name="legged-controller",
            question="the wheel-legged controller's leg length and roll damping",
            kind="controller",
            tasks=("bbbench/LeggedBumps-v0", "bbbench/LeggedObstacles-v0"),
            candidates=tuple(
                Candidate(label, slug, keywords)
                for label, slug, keywords in [
                    ("0.15 m, k_roll 0, k_roll_rate 0.1", "shipped", {}),
                    ("0.12 m", "length-0.12", {"leg_length": 0.12}),
                    ("0.18 m", "length-0.18", {"leg_length": 0.18}),
                    ("k_roll_rate 0", "roll-rate-0", {"k_roll_rate": 0.0}),
                    ("k_roll_rate 0.05", "roll-rate-0.05", {"k_roll_rate": 0.05}),
                    ("k_roll_rate 0.2", "roll-rate-0.2", {"k_roll_rate": 0.2}),
                    ("k_roll 0.5", "roll-0.5", {"k_roll": 0.5}),
                ]
            ),
            shipped="0.15 m, k_roll 0, k_roll_rate 0.1",
            rule=BEST + " (the mean over the two terrain tasks; each setting changed alone)",
            was="the evaluation seeds (the controller's docstring)",
        ),
        Choice(
            name="pushrecovery-growth",
            question="PushRecovery-v0's shove growth (N s per s)",
            kind="task",
            tasks=("bbbench/PushRecovery-v0",),
            candidates=tuple(
                Candidate(f"{growth}", f"growth-{growth}", {"growth": growth})
                for growth in (0.06, 0.065, 0.068, 0.07, 0.075)
            ),
            shipped="0.068",
            rule="PD finishes 20-60% of the episodes (the calibration band of the task)",
            was="30-40 evaluation seeds, then all 100: PD finished 47 of 100 at 0.068",
        ),
        *(_difficulty(*row) for row in DIFFICULTIES),
    ]
}


# -- training a recipe's candidates --------------------------------------------------


def candidate_folder(choice: Choice, candidate: Candidate) -> Path:
    return FOLDER / choice.name / candidate.slug


def candidate_recipe(choice: Choice, candidate: Candidate) -> dict[str, Any]:
    """The shipped recipe of the candidate's task with the candidate's keys changed: a
    recipe file of one task, in the shipped file's format (anchors resolved)."""
    from bbbench.training.recipe_files import read_recipe_file

    task = candidate.value["task"]
    shipped = read_recipe_file(choice.algorithm)[task]
    return {task: {**shipped, **candidate.value["override"]}}


def train(choice: Choice) -> None:
    """Train each candidate that is neither on the board nor trained yet (seed 0)."""
    for candidate in choice.candidates:
        folder = candidate_folder(choice, candidate)
        if candidate.board_run or (folder / "policy.zip").exists():
            continue
        folder.mkdir(parents=True, exist_ok=True)
        for name in ("train.json", "curve.json", "curve.png", "results.json"):
            # a clone's candidate, its policy out of git: trained again, its records made
            # again in place (git diff shows any difference; the record names the SHA-256)
            (folder / name).unlink(missing_ok=True)
        recipe_path = folder / "recipe.yml"
        recipe_path.write_text(yaml.safe_dump(candidate_recipe(choice, candidate)))
        command = [
            "bbbench", "train", candidate.value["task"], "--algo", choice.algorithm,
            "--seed", "0", "--recipe", str(recipe_path.relative_to(ROOT)),
            "--out", str((folder / "policy.zip").relative_to(ROOT)),
        ]  # fmt: skip
        print(f"{choice.name}: {candidate.label}: {' '.join(command)}", flush=True)
        start = time.monotonic()
        with open(folder / "train.log", "w") as log:
            subprocess.run(command, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT, check=True)
        print(f"  {time.monotonic() - start:.0f} s", flush=True)


# -- scoring every candidate on the validation seeds ----------------------------------


BAND = (0.2, 0.6)  # a task calibration's share of episodes its classical controller finishes


def candidate_policy(choice: Choice, candidate: Candidate):
    """(the policy to play, its name in the record) for one candidate."""
    from bbbench.policies import classical_controller, load_policy
    from bbbench.policies.controllers.builtin import LeggedPolicy
    from bbbench.policies.controllers.legged import LeggedController
    from bbbench.policies.policy import PDActor

    if choice.kind == "recipe":
        if candidate.board_run:
            method, run = candidate.board_run.split("/")
            path = BOARD / method / "runs" / run / "policy.zip"
        else:
            path = candidate_folder(choice, candidate) / "policy.zip"
        statistics = path.parent / "vecnormalize.pkl"  # a board run's, beside its policy
        return (
            load_policy(path, vecnormalize=statistics if statistics.is_file() else None),
            str(path.relative_to(ROOT)),
        )
    if choice.kind == "controller":
        keywords = candidate.value

        class Setting(LeggedPolicy):  # the legged controller with one setting changed
            def actor(self, task_id: str, deterministic: bool = True):
                return PDActor(LeggedController(**keywords))

        shown = ", ".join(f"{key}={value}" for key, value in keywords.items())
        return Setting(), f"legged({shown})"
    name = classical_controller(choice.tasks[0])
    return load_policy(name), name


def candidate_tasks(choice: Choice, candidate: Candidate) -> list:
    """The task specs a candidate plays: the suite's, or (a task's calibration) its variant."""
    from bbbench.tasks.perturbations import Push
    from bbbench.tasks.suite import spec

    tasks = [spec(task_id) for task_id in choice.tasks]
    if choice.kind != "task":
        return tasks
    setting = candidate.value
    if "growth" in setting:
        (push,) = [p for p in tasks[0].perturbations if isinstance(p, Push)]
        varied = dataclasses.replace(push, growth=setting["growth"])
        return [dataclasses.replace(tasks[0], perturbations=(varied,))]
    return [tasks[0].with_difficulty(setting["difficulty"])]


def figures(task, episodes) -> dict[str, Any]:
    from bbbench.evaluation.results import aggregate

    summary = aggregate(task, episodes)
    return {
        "normalized": summary["normalized_score"],
        "normalized_ci": summary["normalized_ci"],
        "finished": summary["success_rate"],
        "mean_return": summary["mean"],
        "returns": [episode.episode_return for episode in episodes],
    }


def probability_of_improvement_of(row: dict[str, Any], shipped: dict[str, Any]):
    """P(a candidate > the value shipped) over their episodes on each task (rliable's)."""
    from bbbench.evaluation.stats import probability_of_improvement

    return probability_of_improvement(
        [np.array(task["returns"]) for task in row["tasks"].values()],
        [np.array(task["returns"]) for task in shipped["tasks"].values()],
    )


def evaluate(choice: Choice, workers: int = 1) -> dict[str, Any]:
    """The choice's record: every candidate on its tasks' validation seeds, and the pick."""
    from bbbench.evaluation import machine
    from bbbench.evaluation.harness import play_tasks
    from bbbench.portable import total

    rows = []
    for candidate in choice.candidates:
        policy, name = candidate_policy(choice, candidate)
        tasks = candidate_tasks(choice, candidate)
        start = time.monotonic()
        played = play_tasks(
            policy, tasks, workers=workers, seeds=[task.seeds(SPLIT) for task in tasks]
        )
        if played.missing:
            raise RuntimeError(f"{choice.name}, {candidate.label}: missing {played.missing}")
        by_task = {
            task_id: figures(task, episodes)
            for task_id, task, episodes in zip(choice.tasks, tasks, played.episodes, strict=True)
        }
        score = total(row["normalized"] for row in by_task.values()) / len(by_task)
        row = {"label": candidate.label, "policy": name, "tasks": by_task, "score": score}
        if choice.kind == "recipe":  # the trained file (kept out of git): its bytes, named
            row["sha256"] = hashlib.sha256((ROOT / name).read_bytes()).hexdigest()
        rows.append(row)
        print(f"{choice.name}: {candidate.label}: {score:.3f} ({time.monotonic() - start:.0f} s)")
    shipped = next(row for row in rows if row["label"] == choice.shipped)
    for row in rows:
        if row is not shipped:
            point, interval = probability_of_improvement_of(row, shipped)
            row["p_over_shipped"] = [point, list(interval)]
    if choice.kind == "task":
        admitted = [
            row["label"]
            for row in rows
            if all(BAND[0] <= task["finished"] <= BAND[1] for task in row["tasks"].values())
        ]
        picked = choice.shipped if choice.shipped in admitted else (admitted or [None])[0]
    else:
        admitted = []
        best = max(rows, key=lambda row: row["score"])
        separated = best is not shipped and best["p_over_shipped"][1][0] > 0.5
        picked = best["label"] if separated else choice.shipped
    seeds = candidate_tasks(choice, choice.candidates[0])[0].seeds(SPLIT)
    return {
        "schema": "bbbench-choice/1",
        "choice": choice.name,
        "question": choice.question,
        "kind": choice.kind,
        "tasks": list(choice.tasks),
        "split": SPLIT,
        "seeds": {"first": seeds[0], "count": len(seeds)},
        "rule": choice.rule,
        "was": choice.was,
        "candidates": rows,
        **({"in_band": admitted} if choice.kind == "task" else {}),
        "picked": picked,
        "shipped": choice.shipped,
        "holds": picked == choice.shipped,
        "command": f"python scripts/choices.py --evaluate {choice.name}",
        "machine": machine.described(machine.record()),
        "date": time.strftime("%Y-%m-%d"),
    }


def record_path(name: str) -> Path:
    return FOLDER / f"{name}.json"


def write_record(record: dict[str, Any]) -> None:
    path = record_path(record["choice"])
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_suffix(".json.partial")
    partial.write_text(json.dumps(record, indent=1) + "\n")
    partial.replace(path)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--list", action="store_true", help="the choices and their state")
    parser.add_argument("--train", nargs="*", metavar="NAME", help="train these choices")
    parser.add_argument(
        "--evaluate", nargs="*", metavar="NAME", help="score these choices' candidates"
    )
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args(argv)
    if args.list:
        for choice in CHOICES.values():
            print(f"{choice.name}: {choice.question} (shipped: {choice.shipped})")
    if args.train is not None:
        for name in args.train or list(CHOICES):
            if CHOICES[name].kind == "recipe":
                train(CHOICES[name])
    if args.evaluate is not None:
        for name in args.evaluate or list(CHOICES):
            write_record(evaluate(CHOICES[name], args.workers))
    return 0


if __name__ == "__main__":
    sys.exit(main())

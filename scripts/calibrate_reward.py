"""The shared reward's calibration: how candidate shapes score the random policy, `stand`
(PD holding 0 m/s) and PD on the first suite's eight latest tasks, on their validation
seeds (the shape was first chosen on the evaluation seeds; it is made again here).

    python scripts/calibrate_reward.py --evaluate [--episodes 100]   # writes the record
    python scripts/calibrate_reward.py --table                       # docs/tasks.md's block

The reward does not change an episode (a new reward version observes and terminates as
its predecessor), so each policy's episodes are played once, recording every step's
pitch and velocity error, and each candidate reward is then summed over the same steps.
The record, `baselines/calibrations/reward.json`, holds each candidate's weights, its
mean return per task and policy, stand and PD normalized (0 = random's mean return under
that reward, 1 = the most an episode earns), and, under the shipped reward, every
bot-episode's return (tests/test_calibrations.py replays some through the real env).

The rule (`RULE`) picks a shape from the record's own figures: among the candidates with
a tail (without one, PPO on Bumps-v2 stood still for its whole budget: docs/notebook.md),
those that keep random < stand <= 0.4 and stand < PD on every velocity-commanded task and
PD within 0.01 of 1 on FlatBalance-v1; of those, the one whose narrowest gap is widest.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

import bbbench
from bbbench.policies import load_policy
from bbbench.portable import total
from bbbench.tasks.reward import RewardWeights, StayUpReward

ROOT = Path(__file__).resolve().parents[1]
RECORD = ROOT / "baselines" / "calibrations" / "reward.json"
SPLIT = "validation"
TASKS = tuple(
    f"bbbench/{name}"
    for name in (
        "FlatBalance-v1",
        "VelocityTracking-v1",
        "NoisySensors-v1",
        "Bumps-v2",
        "Obstacles-v2",
        "Slopes-v2",
        "MultiBalance-v1",
        "MultiBumps-v1",
    )
)
STILL = "bbbench/FlatBalance-v1"  # the one task whose target is always 0 m/s
POLICIES = ("random", "stand", "pd")
SHIPPED = StayUpReward()
SHIPPED_LABEL = "share 0.10, tail 0.1 over 2 m/s (shipped)"
CANDIDATES = {
    "first reward (v0, -v1 terrain)": RewardWeights(),
    "share 0.15, no tail": dataclasses.replace(SHIPPED, upright_share=0.15, tail_share=0.0),
    "share 0.10, no tail": dataclasses.replace(SHIPPED, tail_share=0.0),
    "share 0.20, no tail": dataclasses.replace(SHIPPED, upright_share=0.20, tail_share=0.0),
    "share 0.15, no tail, width 0.35 m/s": dataclasses.replace(
        SHIPPED, upright_share=0.15, tail_share=0.0, velocity_width=0.35
    ),
    SHIPPED_LABEL: SHIPPED,
    "share 0.10, tail 0.2 over 2 m/s": dataclasses.replace(SHIPPED, tail_share=0.2),
    "share 0.15, tail 0.1 over 2 m/s": dataclasses.replace(SHIPPED, upright_share=0.15),
    "share 0.10, tail 0.1 over 3 m/s": dataclasses.replace(SHIPPED, tail_width=3.0),
}
STAND_CEILING = 0.4
RULE = (
    "among the shapes with a tail, those with random < stand <= 0.4 and stand < PD on every "
    "velocity-commanded task and PD >= 0.99 on FlatBalance-v1; of those, the one whose "
    "narrowest gap of PD over stand is widest"
)


def record_steps(task_id: str, policy_name: str, episodes: int) -> list[np.ndarray]:
    """Per bot-episode, an array of (pitch, velocity error) per step played."""
    task = bbbench.spec(task_id)
    actor = load_policy(policy_name).actor(task_id)
    runs = []
    for seed in task.seeds(SPLIT)[:episodes]:
        rng = np.random.default_rng(seed)
        if task.multi_agent:
            env = bbbench.make_parallel(task_id)
            observations, _ = env.reset(seed=seed)
            steps = {agent: [] for agent in env.agents}
            while env.agents:
                batch = np.stack([observations[agent] for agent in env.agents])
                actions = actor(batch, [rng] * len(batch))
                observations, _, _, _, infos = env.step(dict(zip(env.agents, actions, strict=True)))
                for agent, info in infos.items():
                    bot = env.scene.bots[env.agent_index[agent]]
                    steps[agent].append((bot.read().pitch, info["velocity_error"]))
            runs += [np.array(rows) for rows in steps.values()]
        else:
            env = bbbench.make(task_id)
            observation, _ = env.reset(seed=seed)
            rows = []
            while True:
                (action,) = actor(observation[None], [rng])
                observation, _, terminated, truncated, info = env.step(action)
                rows.append((env.unwrapped.scene.bots[0].read().pitch, info["velocity_error"]))
                if terminated or truncated:
                    break
            runs.append(np.array(rows))
        env.close()
    return runs


def episode_return(reward, run: np.ndarray) -> float:
    """A bot-episode's return under `reward`, summed step by step as the env sums it."""
    return total(total(reward.terms(pitch, error)) for pitch, error in run)


def weights(reward) -> dict[str, Any]:
    return {"class": type(reward).__name__, **dataclasses.asdict(reward)}


def evaluate(episodes: int) -> dict[str, Any]:
    """The record: every candidate's figures on the tasks' validation seeds, and the pick."""
    from bbbench.evaluation import machine

    start = time.monotonic()
    played = {}
    for task_id in TASKS:
        played[task_id] = {name: record_steps(task_id, name, episodes) for name in POLICIES}
        print(f"{task_id}: played ({time.monotonic() - start:.0f} s)", file=sys.stderr)
    rows = []
    for label, reward in CANDIDATES.items():
        tasks = {}
        for task_id in TASKS:
            returns = {
                name: [episode_return(reward, run) for run in played[task_id][name]]
                for name in POLICIES
            }
            means = {name: total(values) / len(values) for name, values in returns.items()}
            best = reward.max_step * bbbench.spec(task_id).max_episode_steps
            tasks[task_id] = {
                "mean_return": means,
                **{
                    name: (means[name] - means["random"]) / (best - means["random"])
                    for name in ("stand", "pd")
                },
                **({"returns": returns} if reward == SHIPPED else {}),
            }
        rows.append({"label": label, "weights": weights(reward), "tasks": tasks})
    seeds = bbbench.spec(TASKS[0]).seeds(SPLIT)[:episodes]
    return {
        "schema": "bbbench-calibration/1",
        "calibration": "the shared reward's shape",
        "tasks": list(TASKS),
        "policies": list(POLICIES),
        "split": SPLIT,
        "seeds": {"first": seeds[0], "count": len(seeds)},
        "rule": RULE,
        "was": "the evaluation seeds (the first 100 of each task)",
        "candidates": rows,
        "picked": pick(rows),
        "shipped": SHIPPED_LABEL,
        "holds": pick(rows) == SHIPPED_LABEL,
        "command": "python scripts/calibrate_reward.py --evaluate",
        "seconds": round(time.monotonic() - start, 1),
        "machine": machine.described(machine.record()),
        "date": time.strftime("%Y-%m-%d"),
    }


def gaps(row: dict[str, Any]) -> dict[str, float]:
    """PD - stand on each velocity-commanded task."""
    return {
        task_id: task["pd"] - task["stand"]
        for task_id, task in row["tasks"].items()
        if task_id != STILL
    }


def admitted(row: dict[str, Any]) -> bool:
    moving = [task for task_id, task in row["tasks"].items() if task_id != STILL]
    return (
        row["weights"].get("tail_share", 0.0) > 0
        and all(
            0 < task["stand"] <= STAND_CEILING and task["stand"] < task["pd"] for task in moving
        )
        and row["tasks"][STILL]["pd"] >= 0.99
    )


def pick(rows: Sequence[dict[str, Any]]) -> str | None:
    """The rule's shape, from the rows' own figures (None: no shape meets it)."""
    passing = [row for row in rows if admitted(row)]
    if not passing:
        return None
    return max(passing, key=lambda row: min(gaps(row).values()))["label"]


def write_record(record: dict[str, Any]) -> None:
    RECORD.parent.mkdir(parents=True, exist_ok=True)
    partial = RECORD.with_suffix(".json.partial")
    partial.write_text(json.dumps(record, indent=1) + "\n")
    partial.replace(RECORD)


def table(record: dict[str, Any]) -> str:
    """docs/tasks.md's block: the table of the record, and what the shipped row keeps."""
    names = [task_id.removeprefix("bbbench/") for task_id in record["tasks"]]
    seeds = record["seeds"]
    lines = [
        f"Each cell is stand / PD on the first {seeds['count']} {record['split']} seeds, "
        "normalized (0 = random's mean return under that reward, 1 = the most an episode "
        f"earns); `python scripts/calibrate_reward.py --evaluate` wrote "
        "`baselines/calibrations/reward.json`:",
        "",
        "| reward | " + " | ".join(names) + " | meets the rule |",
        "|---|" + "---:|" * len(names) + "---|",
    ]
    for row in record["candidates"]:
        cells = [f"{task['stand']:.3f} / {task['pd']:.3f}" for task in row["tasks"].values()]
        meets = "yes" if admitted(row) else "no"
        lines.append(f"| {row['label']} | " + " | ".join(cells) + f" | {meets} |")
    shipped = next(row for row in record["candidates"] if row["label"] == record["shipped"])
    moving = {k: v for k, v in shipped["tasks"].items() if k != STILL}
    narrowest = min(gaps(shipped), key=gaps(shipped).get)
    still = shipped["tasks"][STILL]
    verdict = (
        "The rule picks the shipped shape."
        if record["holds"]
        else f"The rule picks **{record['picked']}**, not the shipped shape."
    )
    lines += [
        "",
        f"{verdict} It keeps stand at most "
        f"{max(task['stand'] for task in moving.values()):.3f} on every task that asks the "
        f"bot to move, PD above it by {min(gaps(shipped).values()):.3f} or more on each of them "
        f"(the narrowest gap is {narrowest.removeprefix('bbbench/')}, "
        f"{moving[narrowest]['stand']:.3f} against {moving[narrowest]['pd']:.3f}), and PD at "
        f"{still['pd']:.3f} on {STILL.removeprefix('bbbench/')}.",
    ]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--evaluate", action="store_true", help="play and write the record")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--table", action="store_true", help="print docs/tasks.md's block")
    args = parser.parse_args(argv)
    if args.evaluate:
        write_record(evaluate(args.episodes))
    if args.table:
        print(table(json.loads(RECORD.read_text())))
    return 0


if __name__ == "__main__":
    sys.exit(main())

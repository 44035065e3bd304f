"""Rendezvous-v0's calibration: the `rendezvous` controller heard and with its messages
muted (`mute_messages=True`), and what the channel is worth to it.

    python scripts/calibrate_rendezvous.py [--seeds training|validation] [--bots 4 8]
                                           [--hold 3,6]
    python scripts/calibrate_rendezvous.py --record   # the validation seeds, 4 and 8 bots
    python scripts/calibrate_rendezvous.py --table    # docs/tasks.md's block, from the record
    python scripts/calibrate_rendezvous.py --seeds validation --policy policy.onnx

`--seeds training` plays training seeds 1000-1019 (the pilots of docs/notebook.md,
"Rendezvous-v0's pilots"); `validation`, the task's 100 validation seeds. `--record`
plays the validation seeds at 4 and 8 bots and keeps every episode's return in
baselines/calibrations/rendezvous.json, which `--table` prints. `--policy` plays a
policy file (or another built-in) instead of the controller. `--hold` plays a candidate
whose goal moves every LOW-HIGH s (the module's `HOLD`) instead of the task's. Each
row: the mean return per bot, normalized against the task's random return and the most
a bot can earn, the episodes no bot fell in, and rliable's P(muted > heard) over the
episodes' returns with its 95% interval (the channel carries the task where the
interval lies below 0.5).
"""

from __future__ import annotations

import argparse
import json
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

import bbbench
import bbbench.tasks.scenarios.rendezvous as rendezvous
from bbbench.evaluation import stats
from bbbench.policies import load_policy

TASK = "bbbench/Rendezvous-v0"
PILOT_SEEDS = range(1000, 1020)
RECORD = Path(__file__).parents[1] / "baselines" / "calibrations" / "rendezvous.json"


def episode(
    job: tuple[str, int, bool, int, tuple[float, float] | None], watch=None
) -> tuple[float, int]:
    """One episode under `policy` (a built-in's name or a file): its mean return per bot
    and its falls. `watch(env, step)`, if given, sees the env before each of its steps."""
    policy, bots, muted, seed, hold = job
    if hold is not None:
        rendezvous.HOLD = hold  # this worker's candidate
    loaded = load_policy(policy)  # the env in its actions (a file's own mode)
    env = bbbench.make_parallel(
        TASK, n_bots=bots, mute_messages=muted, action_mode=loaded.action_mode
    )
    act = loaded.actor(TASK)
    observations, _ = env.reset(seed=seed)
    returns = dict.fromkeys(env.possible_agents, 0.0)
    falls = 0
    # A recurrent policy's state, a row per bot still in the episode (zeros at its start).
    states = act.initial_state(len(env.agents)) if hasattr(act, "initial_state") else None
    step = 0
    while env.agents:
        if watch is not None:
            watch(env, step)
        step += 1
        agents = env.agents
        stacked = np.stack([observations[agent] for agent in agents])
        if states is None:
            actions = act(stacked, None)
        else:
            actions, states = act.step(stacked, states)
        observations, rewards, terminations, _, _ = env.step(
            dict(zip(agents, actions, strict=True))
        )
        if states is not None:
            states = states[[agents.index(agent) for agent in env.agents]]
        for agent, reward in rewards.items():
            returns[agent] += reward
        falls += sum(terminations.values())
    env.close()
    return float(np.mean(list(returns.values()))), falls


def row(bots: int, heard: list[float], muted: list[float], whole: int) -> str:
    """A table row: each side's mean return and normalized score, the episodes no bot fell
    in (heard), and P(muted > heard) with its interval."""
    task = bbbench.spec(TASK)
    zero, best = task.random_return, task.max_return
    point, (low, high) = stats.probability_of_improvement([np.array(muted)], [np.array(heard)])
    said, quiet = float(np.mean(heard)), float(np.mean(muted))
    return (
        f"| {bots} | {said:.1f}, {(said - zero) / (best - zero):.3f}, {whole}/{len(heard)} | "
        f"{quiet:.1f}, {(quiet - zero) / (best - zero):.3f} | "
        f"{point:.3f} [{low:.3f}, {high:.3f}] |"
    )


HEADER = (
    "| bots | heard: mean return, normalized, episodes no bot fell in "
    "| muted: mean return, normalized | P(muted > heard) [95% CI] |\n|---|---|---|---|"
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", choices=("training", "validation"), default="training")
    parser.add_argument("--bots", type=int, nargs="*", default=[4])
    parser.add_argument("--hold", help="LOW,HIGH s: a candidate's goal hold")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--policy", default="rendezvous", help="a built-in or a policy file")
    parser.add_argument("--record", action="store_true", help="write the validation record")
    parser.add_argument("--table", action="store_true", help="print docs/tasks.md's block")
    args = parser.parse_args()
    if args.table:
        record = json.loads(RECORD.read_text())
        print(HEADER)
        for bots, played in record["bots"].items():
            print(row(int(bots), played["heard"], played["muted"], played["whole"]))
        return
    if args.record:
        args.seeds, args.bots, args.hold = "validation", [4, 8], None
    task = bbbench.spec(TASK)
    seeds = list(PILOT_SEEDS if args.seeds == "training" else task.validation_seeds)
    hold = tuple(float(value) for value in args.hold.split(",")) if args.hold else None
    record = {"task": TASK, "seeds": args.seeds, "bots": {}}
    print(HEADER)
    with ProcessPoolExecutor(args.workers) as pool:
        for bots in args.bots:
            played = {
                muted: list(pool.map(episode, [(args.policy, bots, muted, s, hold) for s in seeds]))
                for muted in (False, True)
            }
            heard, muted = ([r for r, _ in played[key]] for key in (False, True))
            whole = sum(falls == 0 for _, falls in played[False])
            record["bots"][str(bots)] = {"heard": heard, "muted": muted, "whole": whole}
            print(row(bots, heard, muted, whole), flush=True)
    if args.record:
        RECORD.parent.mkdir(parents=True, exist_ok=True)
        partial = RECORD.with_suffix(".json.partial")
        partial.write_text(json.dumps(record, indent=1) + "\n")
        partial.replace(RECORD)


if __name__ == "__main__":
    main()

"""The team tasks' calibration (issue 39): the suite's team tasks, and the candidates
explored before them, played by the random policy, PD alone on every bot (naive: a
follower holds the 0 it observes) and the team controller
(`bbbench.policies.controllers.team`), on the first seeds of a split (the candidates were
first played on the evaluation seeds); with `--shared-ppo`, also MultiBalance-v1's shared
PPO.

    python scripts/calibrate_teams.py [--episodes 100] [--workers 2] [--only TEXT]
        [--shared-ppo] [--seeds evaluation|validation]
    python scripts/calibrate_teams.py --evaluate   # the suite's three, validation seeds:
                                                   # baselines/calibrations/teams.json
    python scripts/calibrate_teams.py --table      # docs/tasks.md's block, from the record

Each candidate is a spec made from MultiBalance-v1's row with a column scenario, a
coupling and a target range (`CANDIDATES`, `bbbench.dev.teams.candidate_task`). A row
says, per policy, the share of episodes finished and the mean team return as a fraction
of the most (0.1 a step), then each policy normalized against random (0 = random's mean
return, 1 = the most), and P(team > naive) with its 95% interval
(`bbbench.evaluation.stats`). The targets a task must meet: team clearly above naive
(the interval above 0.5), team at most 0.7 normalized or at most 60% finished, random
finishing none.
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from bbbench.dev.teams import candidate_task
from bbbench.envs.multi import MultiBalanceEnv
from bbbench.evaluation import stats
from bbbench.evaluation.play import MultiEpisode
from bbbench.policies import load_policy
from bbbench.policies.controllers.pd import PDController
from bbbench.policies.controllers.team import TeamController
from bbbench.tasks.scenarios import Beam, Tether
from bbbench.tasks.spec import EVAL_SEEDS, VALIDATION_SEEDS
from bbbench.tasks.suite import spec
from bbbench.terrain import Bumps, HeightfieldTerrain

POLICIES = ("random", "naive", "team")
TEAM_TASKS = ("bbbench/BeamCarry-v0", "bbbench/BeamCarryBumps-v0", "bbbench/Convoy-v0")
# MultiBalance-v1's shared PPO (seed 0, on the board), placed in a team: its 17 values are
# the shared five and its 3 nearest bots' offsets and velocities, nearest first, zeros
# beyond; a column bot's neighbours are the bots ahead and behind (`crossing_view`).
SHARED_PPO = Path(__file__).parents[1] / "leaderboards/submissions/ppo-multibalance-v1-s0"
RECORD = Path(__file__).parents[1] / "baselines" / "calibrations" / "teams.json"
SPLITS = {"evaluation": EVAL_SEEDS, "validation": VALIDATION_SEEDS}
TEAM_CEILING, FINISHED_CEILING = 0.7, 0.6  # team at most this normalized, or finished


def crossing_view(observation: np.ndarray, layout: list[str]) -> np.ndarray:
    """A column bot's observation as MultiBalance-v1 lays it out (17 values)."""
    index = {name: i for i, name in enumerate(layout)}
    view = np.zeros(17, dtype=np.float32)
    view[:5] = observation[:5]
    slot = 5
    for where in ("ahead", "behind"):
        if observation[index[f"{where}_present"]] == 1.0:
            fields = ("right", "forward", "right_velocity", "forward_velocity")
            view[slot : slot + 4] = [observation[index[f"{where}_{f}"]] for f in fields]
            slot += 4
    return view


def _hills(difficulty: float, extra_height: float = 0.06) -> HeightfieldTerrain:
    """-v0's smooth hills (0.02 m + `extra_height` x difficulty) on a 4 x 36 m strip about
    the column, which goes back and forth: about as many nodes as MultiBumps' square."""
    return HeightfieldTerrain(
        generator=Bumps(extra_height=extra_height),
        difficulty=difficulty,
        size=(4.0, 36.0),
        start_margin=18.0,
        start_pad=1.2,
    )


CANDIDATES = {
    **{task_id: spec(task_id) for task_id in TEAM_TASKS},
    "beam 1.5 kg, 3 bots, [-2, 2] m/s": candidate_task(Beam(), 3, 2.0),
    "beam 1.0 kg, 3 bots, [-2, 2] m/s": candidate_task(Beam(mass=1.0), 3, 2.0),
    "beam 2.0 kg, 4 bots, [-2, 2] m/s": candidate_task(Beam(mass=2.0), 4, 2.0),
    "beam 1.5 kg, 3 bots, [-2, 2] m/s, hills 0.3": candidate_task(
        Beam(), 3, 2.0, terrain=_hills(0.3)
    ),
    "beam 1.5 kg, 3 bots, [-2, 2] m/s, hills 0.6": candidate_task(
        Beam(), 3, 2.0, terrain=_hills(0.6)
    ),
    "beam 1.5 kg, 3 bots, [-2, 2] m/s, hills 1.0": candidate_task(
        Beam(), 3, 2.0, terrain=_hills(1.0)
    ),
    "beam 1.5 kg, 3 bots, [-2, 2] m/s, hills 0.12 m": candidate_task(
        Beam(), 3, 2.0, terrain=_hills(1.0, extra_height=0.10)
    ),
    "convoy (20 N/m, 5 N s/m), 3 bots, [-2, 2] m/s": candidate_task(Tether(), 3, 2.0),
    "convoy (20 N/m, 5 N s/m), 3 bots, [-1, 1] m/s": candidate_task(Tether(), 3, 1.0),
}


def play(job: tuple[str, str, int]) -> tuple[int, float]:
    """(length, team return) of one episode of a candidate under one policy."""
    name, policy, seed = job
    env = MultiBalanceEnv(CANDIDATES[name])
    pd = PDController()
    team = TeamController.for_scenario(env.scene.scenario)
    rng = np.random.default_rng([0x5EED, seed])
    controls = {
        "random": lambda observation: int(rng.integers(9)),
        "naive": lambda observation: pd(observation[:5]),
        "team": team,
    }
    if policy == "shared PPO":
        layout = [f.name for f in env.scene.scenario.layout]
        shared = load_policy(
            SHARED_PPO / "policy.zip", vecnormalize=SHARED_PPO / "vecnormalize.pkl"
        )
        ppo = shared.actor("bbbench/MultiBalance-v1")

        def act(batch, _):
            return ppo(np.stack([crossing_view(row, layout) for row in batch]))
    else:
        control = controls[policy]

        def act(batch, _):
            return [control(row) for row in batch]

    # The team reward is every bot's: the per-bot mean return is the team's.
    result = MultiEpisode(env, act, seed).play()
    return result.length, result.episode_return


def figures(name: str, policies: tuple[str, ...], seeds, pool, play=play, best=None) -> dict:
    """Each policy's episodes of a candidate: (length, team return) per seed, the share
    finished, the normalized mean, and P(team > naive) with the targets it meets. `play`
    plays a job (name, policy, seed); `best`, the most a team earns (None: the
    candidate's)."""
    jobs = [(name, policy, seed) for policy in policies for seed in seeds]
    played = dict(zip(jobs, pool.map(play, jobs, chunksize=4), strict=True))
    best = CANDIDATES[name].max_return if best is None else best
    returns = {p: [played[name, p, seed][1] for seed in seeds] for p in policies}
    lengths = {p: [played[name, p, seed][0] for seed in seeds] for p in policies}
    zero = float(np.mean(returns["random"]))
    normalized = {p: (np.array(returns[p]) - zero) / (best - zero) for p in policies}
    point, (low, high) = stats.probability_of_improvement(
        [normalized["team"]], [normalized["naive"]]
    )
    rows = {
        p: {
            "returns": returns[p],
            "lengths": lengths[p],
            "finished": float(np.mean([length == 1500 for length in lengths[p]])),
            "mean_return": float(np.mean(returns[p])),
            "normalized": float(normalized[p].mean()),
        }
        for p in policies
    }
    team = rows["team"]
    meets = bool(
        low > 0.5
        and (team["normalized"] <= TEAM_CEILING or team["finished"] <= FINISHED_CEILING)
        and rows["random"]["finished"] == 0
    )
    return {"policies": rows, "p_team_over_naive": [point, [low, high]], "meets": meets}


def explore(args) -> None:
    """Print a row per candidate (the first way of the calibration)."""
    seeds = SPLITS[args.seeds][: args.episodes]
    policies = (*POLICIES, "shared PPO") if args.shared_ppo else POLICIES
    print(f"{args.episodes} {args.seeds} seeds per policy; finished, mean return / max")
    with ProcessPoolExecutor(args.workers) as pool:
        for name, task in CANDIDATES.items():
            if args.only not in name:
                continue
            found = figures(name, policies, seeds, pool)
            rows, best = found["policies"], task.max_return
            point, (low, high) = found["p_team_over_naive"]
            cells = "; ".join(
                f"{p} {rows[p]['finished']:.0%} {rows[p]['mean_return'] / best:.3f}"
                for p in policies
            )
            scores = ", ".join(f"{p} {rows[p]['normalized']:.3f}" for p in policies[1:])
            print(
                f"{name}: {cells}; normalized {scores}; P(team > naive) {point:.2f} "
                f"[{low:.2f}, {high:.2f}]",
                flush=True,
            )


def evaluate(workers: int) -> dict:
    """The record: the suite's three team tasks on their 100 validation seeds."""
    start = time.monotonic()
    with ProcessPoolExecutor(workers) as pool:
        tasks = {name: figures(name, POLICIES, VALIDATION_SEEDS, pool) for name in TEAM_TASKS}
    extra = {"was": "the evaluation seeds"}
    return validation_record("the team tasks", extra, tasks, "calibrate_teams.py", start)


def validation_record(
    calibration: str, extra: dict, tasks: dict, script: str, start: float
) -> dict:
    """A calibration's record of `tasks` (`figures` of each) on the validation seeds,
    against the team tasks' targets; `extra` keys go before the tasks."""
    from bbbench.evaluation import machine

    return {
        "schema": "bbbench-calibration/1",
        "calibration": calibration,
        "split": "validation",
        "seeds": {"first": VALIDATION_SEEDS[0], "count": len(VALIDATION_SEEDS)},
        "rule": (
            "team clearly above naive (P's interval above 0.5), team at most "
            f"{TEAM_CEILING} normalized or at most {FINISHED_CEILING:.0%} finished, random "
            "finishing none"
        ),
        **extra,
        "tasks": tasks,
        "holds": all(task["meets"] for task in tasks.values()),
        "command": f"python scripts/{script} --evaluate",
        "seconds": round(time.monotonic() - start, 1),
        "machine": machine.described(machine.record()),
        "date": time.strftime("%Y-%m-%d"),
    }


def table(record: dict) -> str:
    """docs/tasks.md's block: the record's table, and whether the targets hold."""
    lines = [
        "| task | random finishes | naive: finished, normalized | team: finished, normalized "
        "| P(team > naive) [95% CI] | meets the targets |",
        "|---|---:|---:|---:|---:|---|",
    ]
    for name, task in record["tasks"].items():
        rows = task["policies"]
        shown = [
            f"{rows[p]['finished']:.0%}, {rows[p]['normalized']:.3f}" for p in ("naive", "team")
        ]
        point, (low, high) = task["p_team_over_naive"]
        lines.append(
            f"| {name.removeprefix('bbbench/')} | {rows['random']['finished']:.0%} | "
            f"{' | '.join(shown)} | {point:.2f} [{low:.2f}, {high:.2f}] | "
            f"{'yes' if task['meets'] else 'no'} |"
        )
    verdict = "Every target holds" if record["holds"] else "**Not every target holds**"
    scores = [task["policies"]["team"]["normalized"] for task in record["tasks"].values()]
    lines += [
        "",
        f"{verdict} on the {record['seeds']['count']} validation seeds: {record['rule']} "
        f"(team {min(scores):.2f}-{max(scores):.2f} normalized: headroom for learning).",
    ]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--only", default="", help="only the candidates whose name has this")
    parser.add_argument("--seeds", choices=sorted(SPLITS), default="validation")
    parser.add_argument(
        "--shared-ppo",
        action="store_true",
        help="also MultiBalance-v1's shared PPO (seed 0), each bot seeing its column "
        "neighbours as its nearest bots",
    )
    parser.add_argument("--evaluate", action="store_true", help="write the suite's record")
    parser.add_argument("--table", action="store_true", help="print docs/tasks.md's block")
    args = parser.parse_args()
    if args.evaluate:
        RECORD.parent.mkdir(parents=True, exist_ok=True)
        partial = RECORD.with_suffix(".json.partial")
        partial.write_text(json.dumps(evaluate(args.workers), indent=1) + "\n")
        partial.replace(RECORD)
    if args.table:
        print(table(json.loads(RECORD.read_text())))
    if not (args.evaluate or args.table):
        explore(args)


if __name__ == "__main__":
    main()

"""The column tasks' calibration (issue 39): candidate team tasks played by the random
policy, PD alone on every bot (naive: a follower holds the 0 it observes) and the team
controller (`bbbench.policies.team`), on the first evaluation seeds.

    python scripts/calibrate_teams.py [--episodes 100] [--workers 2]

Each candidate is a spec made from MultiBalance-v1's row with a column scenario, a
coupling and a target range (`CANDIDATES`, `bbbench.dev.teams.candidate_task`). A row
says, per policy, the share of episodes finished and the mean team return as a fraction
of the most (0.1 a step), then naive and team normalized against random (0 = random's
mean return, 1 = the most), and P(team > naive) with its 95% interval
(`bbbench.evaluation.stats`). The targets a task
must meet: team clearly above naive (the interval above 0.5), team at most 0.7
normalized or at most 60% finished, random finishing none.
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from bbbench.dev.teams import candidate_task
from bbbench.envs.multi import MultiBalanceEnv
from bbbench.evaluation import stats
from bbbench.evaluation.play import MultiEpisode
from bbbench.policies.pd import PDController
from bbbench.policies.team import TeamController
from bbbench.tasks.coupling import Beam, Tether
from bbbench.tasks.spec import EVAL_SEEDS

POLICIES = ("random", "naive", "team")


CANDIDATES = {
    "beam 1.5 kg, 3 bots, [-2, 2] m/s": candidate_task(Beam(), 3, 2.0),
    "beam 1.0 kg, 3 bots, [-2, 2] m/s": candidate_task(Beam(mass=1.0), 3, 2.0),
    "beam 2.0 kg, 4 bots, [-2, 2] m/s": candidate_task(Beam(mass=2.0), 4, 2.0),
    "convoy (20 N/m, 5 N s/m), 3 bots, [-2, 2] m/s": candidate_task(Tether(), 3, 2.0),
    "convoy (20 N/m, 5 N s/m), 3 bots, [-1, 1] m/s": candidate_task(Tether(), 3, 1.0),
}


def play(job: tuple[str, str, int]) -> tuple[int, float]:
    """(length, team return) of one episode of a candidate under one policy."""
    name, policy, seed = job
    env = MultiBalanceEnv(CANDIDATES[name])
    pd = PDController()
    team = TeamController([f.name for f in env.scene.scenario.layout])
    rng = np.random.default_rng([0x5EED, seed])
    controls = {
        "random": lambda observation: int(rng.integers(9)),
        "naive": lambda observation: pd(observation[:5]),
        "team": team,
    }
    control = controls[policy]
    # The team reward is every bot's: the per-bot mean return is the team's.
    result = MultiEpisode(env, lambda batch, _: [control(row) for row in batch], seed).play()
    return result.length, result.episode_return


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    seeds = EVAL_SEEDS[: args.episodes]
    print(f"{args.episodes} evaluation seeds per policy; finished, mean return / max")
    with ProcessPoolExecutor(args.workers) as pool:
        for name, task in CANDIDATES.items():
            jobs = [(name, policy, seed) for policy in POLICIES for seed in seeds]
            played = dict(zip(jobs, pool.map(play, jobs, chunksize=4), strict=True))
            best = task.max_return
            returns = {
                policy: np.array([played[name, policy, seed][1] for seed in seeds])
                for policy in POLICIES
            }
            finished = {
                policy: np.mean([played[name, policy, seed][0] == 1500 for seed in seeds])
                for policy in POLICIES
            }
            zero = returns["random"].mean()
            normalized = {p: (returns[p] - zero) / (best - zero) for p in ("naive", "team")}
            point, (low, high) = stats.probability_of_improvement(
                [normalized["team"]], [normalized["naive"]]
            )
            cells = "; ".join(
                f"{p} {finished[p]:.0%} {returns[p].mean() / best:.3f}" for p in POLICIES
            )
            print(
                f"{name}: {cells}; normalized naive {normalized['naive'].mean():.3f}, team "
                f"{normalized['team'].mean():.3f}; P(team > naive) {point:.2f} "
                f"[{low:.2f}, {high:.2f}]",
                flush=True,
            )


if __name__ == "__main__":
    main()

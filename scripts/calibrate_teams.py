"""The team tasks' calibration (issue 39): the suite's team tasks, and the candidates
explored before them, played by the random policy, PD alone on every bot (naive: a
follower holds the 0 it observes) and the team controller (`bbbench.policies.controllers.team`), on
the first evaluation seeds; with `--shared-ppo`, also MultiBalance-v1's shared PPO.

    python scripts/calibrate_teams.py [--episodes 100] [--workers 2] [--only TEXT]
        [--shared-ppo]

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
from bbbench.tasks.spec import EVAL_SEEDS
from bbbench.tasks.suite import spec
from bbbench.terrain import Bumps, HeightfieldTerrain

POLICIES = ("random", "naive", "team")
TEAM_TASKS = ("bbbench/BeamCarry-v0", "bbbench/BeamCarryBumps-v0", "bbbench/Convoy-v0")
# MultiBalance-v1's shared PPO (seed 0, on the board), placed in a team: its 17 values are
# the shared five and its 3 nearest bots' offsets and velocities, nearest first, zeros
# beyond; a column bot's neighbours are the bots ahead and behind (`crossing_view`).
SHARED_PPO = Path(__file__).parents[1] / "leaderboards/submissions/ppo-multibalance-v1-s0"


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--only", default="", help="only the candidates whose name has this")
    parser.add_argument(
        "--shared-ppo",
        action="store_true",
        help="also MultiBalance-v1's shared PPO (seed 0), each bot seeing its column "
        "neighbours as its nearest bots",
    )
    args = parser.parse_args()
    seeds = EVAL_SEEDS[: args.episodes]
    print(f"{args.episodes} evaluation seeds per policy; finished, mean return / max")
    with ProcessPoolExecutor(args.workers) as pool:
        for name, task in CANDIDATES.items():
            if args.only not in name:
                continue
            policies = (*POLICIES, "shared PPO") if args.shared_ppo else POLICIES
            jobs = [(name, policy, seed) for policy in policies for seed in seeds]
            played = dict(zip(jobs, pool.map(play, jobs, chunksize=4), strict=True))
            best = task.max_return
            returns = {
                policy: np.array([played[name, policy, seed][1] for seed in seeds])
                for policy in policies
            }
            finished = {
                policy: np.mean([played[name, policy, seed][0] == 1500 for seed in seeds])
                for policy in policies
            }
            zero = returns["random"].mean()
            normalized = {p: (returns[p] - zero) / (best - zero) for p in policies[1:]}
            point, (low, high) = stats.probability_of_improvement(
                [normalized["team"]], [normalized["naive"]]
            )
            cells = "; ".join(
                f"{p} {finished[p]:.0%} {returns[p].mean() / best:.3f}" for p in policies
            )
            scores = ", ".join(f"{p} {normalized[p].mean():.3f}" for p in policies[1:])
            print(
                f"{name}: {cells}; normalized {scores}; P(team > naive) {point:.2f} "
                f"[{low:.2f}, {high:.2f}]",
                flush=True,
            )


if __name__ == "__main__":
    main()

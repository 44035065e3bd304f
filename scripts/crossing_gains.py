"""The crossing controller's gains, chosen on training seeds (never the eval seeds).

    python scripts/crossing_gains.py [--task bbbench/MultiBalance-v1] [--episodes 60]

Plays PD and the crossing law (`bbbench.policies.controllers.crossing.CrossingController`) with each
set of gains below on the same training seeds (0 to `--episodes` - 1: the training
range, disjoint from the eval seeds) and prints the mean return, the share of whole
episodes (no bot fell) and P(law > PD) over paired episodes, as JSON lines.
"""

from __future__ import annotations

import argparse
import itertools
import json

import numpy as np

from bbbench.evaluation.episodes import LockstepPlayer
from bbbench.policies import load_policy
from bbbench.policies.controllers.crossing import CrossingController
from bbbench.policies.policy import PDActor

GRID = {
    "margin": (0.6, 1.0, 1.4),
    "slow": (0.0, 0.4),
    "fast": (1.0, 1.3, 1.6),
}


def play(actor, task_id: str, seeds: list[int]) -> tuple[np.ndarray, np.ndarray]:
    player = LockstepPlayer(actors={task_id: actor}, action_mode="discrete", sampled=False)
    played = player.play(task_id, seeds)
    player.close()
    returns = np.array([episode.episode_return for episode in played])
    whole = np.array([episode.success for episode in played], dtype=float)
    return returns, whole


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="bbbench/MultiBalance-v1")
    parser.add_argument("--episodes", type=int, default=60)
    args = parser.parse_args()
    seeds = list(range(args.episodes))
    pd_returns, pd_whole = play(load_policy("pd").actor(args.task), args.task, seeds)
    print(json.dumps({"law": "pd", "mean": pd_returns.mean(), "whole": pd_whole.mean()}))
    for values in itertools.product(*GRID.values()):
        gains = dict(zip(GRID, values, strict=True))
        returns, whole = play(PDActor(CrossingController(**gains)), args.task, seeds)
        wins = (returns > pd_returns).mean() + 0.5 * (returns == pd_returns).mean()
        report = {"law": gains, "mean": returns.mean(), "whole": whole.mean(), "p": wins}
        print(json.dumps(report), flush=True)


if __name__ == "__main__":
    main()

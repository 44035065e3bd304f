"""Training speed: the tutorial's DQN recipe against bbbench's FlatBalance-v0 recipe, until
the bot stands.

    python benchmarks/bench_train.py [--seeds 0 1 2] [--check-every 5000]

The tutorial trains SB3's DQN on its balancing robot and says it stands "after around
2 minutes". Here, in one run on one machine, for each seed:

(a) the tutorial's recipe on FlatBalance-v0: DQN, a budget of 200,000 steps, learning
    rate 1e-3, replay buffer 50,000, exploration fraction 0.1, final epsilon 0.02, an
    MLP of two 16-unit layers (SB3's defaults otherwise), one env;
(b) bbbench's recipe (`bbbench/training/recipes/ppo.yml`, FlatBalance-v0: PPO, 8 envs).

Every `--check-every` steps training pauses and the policy plays 20 episodes on
training seeds (`bbbench.training.evaluation_seeds`, deterministic actions); the bot
"stands" when their mean length is at least 1400 of 1500 steps. Reported: the steps
and the training wall time (the checks' own time excluded) until then. torch runs
on one thread in both. The two recipes alternate, seed by seed.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import torch
from stable_baselines3 import DQN
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.env_util import make_vec_env

import bbbench  # noqa: F401  (registers the tasks)
from bbbench.evaluation.episodes import LockstepPlayer
from bbbench.policies.policy import TorchActor
from bbbench.training import evaluation_seeds, recipe
from bbbench.training.sb3.train import build_model, training_env

FLAT = "bbbench/FlatBalance-v0"
STANDS = 1400  # mean episode length, of 1500
EPISODES = 20


class UntilItStands(BaseCallback):
    """Stops training when the policy stands; times training without the checks."""

    def __init__(self, every: int) -> None:
        super().__init__()
        self.every, self.next_at = every, every
        self.runner = LockstepPlayer(actors={}, action_mode="discrete", sampled=False)
        self.checking = 0.0
        self.began = time.perf_counter()
        self.stood: tuple[int, float] | None = None

    def _on_step(self) -> bool:
        if self.num_timesteps < self.next_at:
            return True
        self.next_at += self.every
        paused = time.perf_counter()
        self.runner.actors[FLAT] = TorchActor(self.model.policy)
        played = self.runner.play(FLAT, evaluation_seeds(FLAT, EPISODES))
        self.checking += time.perf_counter() - paused
        if np.mean([episode.length for episode in played]) >= STANDS:
            self.stood = (self.num_timesteps, paused - self.began - self.checking)
            return False
        return True


def tutorial(seed: int):
    env = make_vec_env(FLAT, n_envs=1, seed=seed)
    model = DQN(
        "MlpPolicy",
        env,
        learning_rate=1e-3,
        buffer_size=50_000,
        exploration_fraction=0.1,
        exploration_final_eps=0.02,
        policy_kwargs={"net_arch": [16, 16]},
        seed=seed,
        device="cpu",
    )
    return model, 200_000


def bbbench_recipe(seed: int):
    plan = recipe("ppo", FLAT)
    env = training_env(plan, [FLAT], plan.n_envs, "discrete", seed)
    return build_model(plan, env, seed), plan.n_timesteps


def until_it_stands(make, seed: int, every: int) -> tuple[int, float] | None:
    model, budget = make(seed)
    callback = UntilItStands(every)
    model.learn(total_timesteps=budget, callback=callback)
    callback.runner.close()
    return callback.stood


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--check-every", type=int, default=5000)
    args = parser.parse_args()
    torch.set_num_threads(1)
    times = {"tutorial DQN": [], "bbbench PPO recipe": []}
    print("| seed | recipe | steps until it stands | training wall time (s) |")
    print("|---|---|---|---|")
    for seed in args.seeds:
        for name, make in (("tutorial DQN", tutorial), ("bbbench PPO recipe", bbbench_recipe)):
            stood = until_it_stands(make, seed, args.check_every)
            if stood is None:
                print(f"| {seed} | {name} | did not stand within its budget | - |", flush=True)
                times[name].append(float("inf"))
            else:
                print(f"| {seed} | {name} | {stood[0]:,} | {stood[1]:.1f} |", flush=True)
                times[name].append(stood[1])
    medians = {name: statistics.median(values) for name, values in times.items()}
    ratio = medians["bbbench PPO recipe"] / medians["tutorial DQN"]
    print(
        f"\nmedian wall time until it stands: tutorial DQN {medians['tutorial DQN']:.1f} s, "
        f"bbbench recipe {medians['bbbench PPO recipe']:.1f} s: **{ratio:.2f}x**"
    )


if __name__ == "__main__":
    main()

"""Train the PPO policies that show learning pays on the -v1 terrain tasks.

    python scripts/train_terrain.py --task bbbench/Bumps-v1 --out bumps-v1.zip
    python scripts/train_terrain.py --task bbbench/Slopes-v1 --fall-penalty 10 --out s.zip

PPO (stable-baselines3, discrete actions, the default 64 x 64 tanh MLP), 8 envs,
on training seeds only (reset() without a seed), at the task's default difficulty.
Policies start from the shipped reference policy (400k steps on
VelocityTracking-v0: it already balances) and train `--steps` more, so the
whole budget is 400k + `--steps`. `--height-scan` trains a policy that observes
the ground ahead (`height_scan=True`): its first layers are the reference's,
widened with zero weights for the 11 scan inputs, so it starts as the reference
and learns what the scan is worth.

`--fall-penalty P` subtracts P from the reward of the step that falls, in
training only (policies are scored with the task's own reward). At 1-2 m/s a bot
held back by terrain can earn nothing per step (the velocity term, up to
-0.1 x 2 m/s, cancels the upright term), and a fall, which ends the episode,
then costs PPO nothing; the penalty makes standing worth it.

Seeded; torch's CPU kernels may still vary across machines, so a shipped file,
not this script, is the result. docs/tasks.md records the commands and scores.
"""

from __future__ import annotations

import argparse
import time
from importlib import resources

import gymnasium
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env

import bbbench  # noqa: F401  (registers the tasks)

HYPERPARAMETERS = {"n_steps": 512, "batch_size": 256, "gamma": 0.995}


def widened(reference: PPO, model: PPO) -> dict[str, torch.Tensor]:
    """The reference's weights for `model`, whose observations are longer: each first
    layer keeps the reference's columns for the shared inputs and gets zeros for the rest."""
    weights = {}
    for name, theirs in reference.policy.state_dict().items():
        ours = model.policy.state_dict()[name]
        if theirs.shape != ours.shape:  # a first layer: (64, 5) into (64, 16)
            padded = torch.zeros_like(ours)
            padded[:, : theirs.shape[1]] = theirs
            theirs = padded
        weights[name] = theirs
    return weights


class FallPenalty(gymnasium.Wrapper):
    """Subtract `penalty` from the reward of the step on which the bot falls."""

    def __init__(self, env: gymnasium.Env, penalty: float) -> None:
        super().__init__(env)
        self.penalty = penalty

    def step(self, action):
        observation, reward, terminated, truncated, info = self.env.step(action)
        return observation, reward - self.penalty * terminated, terminated, truncated, info


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--steps", type=int, default=600_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--fall-penalty", type=float, default=0.0)
    parser.add_argument("--height-scan", action="store_true")
    parser.add_argument("--gamma", type=float, default=HYPERPARAMETERS["gamma"])
    args = parser.parse_args()
    hyperparameters = {**HYPERPARAMETERS, "gamma": args.gamma}
    torch.set_num_threads(1)  # one process per core; more threads only contend
    env = make_vec_env(
        args.task,
        n_envs=8,
        seed=args.seed,
        env_kwargs={"height_scan": True} if args.height_scan else None,
        wrapper_class=FallPenalty if args.fall_penalty else None,
        wrapper_kwargs={"penalty": args.fall_penalty} if args.fall_penalty else None,
    )
    reference = resources.files("bbbench.policies") / "reference.zip"
    with resources.as_file(reference) as path:  # our own file: SB3's load is safe here
        if args.height_scan:
            model = PPO("MlpPolicy", env, seed=args.seed, device="cpu", **hyperparameters)
            model.policy.load_state_dict(widened(PPO.load(path, device="cpu"), model))
        else:
            model = PPO.load(
                path, env=env, device="cpu", seed=args.seed, custom_objects=hyperparameters
            )
    model.verbose = 1
    began = time.perf_counter()
    model.learn(total_timesteps=args.steps, log_interval=10)
    model.save(args.out)
    print(f"trained {args.steps} steps on {args.task} in {time.perf_counter() - began:.0f} s")


if __name__ == "__main__":
    main()

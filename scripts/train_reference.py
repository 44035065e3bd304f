"""Train the reference policy shipped as bbbench/policies/reference.zip.

    python scripts/train_reference.py --out bbbench/policies/reference.zip

PPO with stable-baselines3's default MLP (64 x 64, tanh), discrete actions, on
VelocityTracking-v0: its targets span FlatBalance's 0 m/s and the terrain
tasks' 0.2-0.8 m/s, so one policy runs on every single-bot task. The run is
seeded; torch's CPU kernels may still vary across machines, so the shipped file
(not this script) is the reference.
"""

from __future__ import annotations

import argparse

from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env

import bbbench  # noqa: F401  (registers the tasks)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--task", default="bbbench/VelocityTracking-v0")
    parser.add_argument("--steps", type=int, default=400_000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    env = make_vec_env(args.task, n_envs=4, seed=args.seed)
    model = PPO("MlpPolicy", env, seed=args.seed, device="cpu", verbose=0)
    model.learn(total_timesteps=args.steps)
    model.save(args.out)


if __name__ == "__main__":
    main()

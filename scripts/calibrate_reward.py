"""The shared reward's calibration: how candidate shapes score the random policy, `stand`
(PD holding 0 m/s) and PD on each latest task's evaluation seeds.

    python scripts/calibrate_reward.py [--episodes 100] [--markdown]

The reward does not change an episode (a new reward version observes and terminates as
its predecessor), so each policy's episodes are played once, recording every step's
pitch and velocity error, and each candidate reward is then summed over the same
steps. A row is a candidate; a column a task, with stand / PD normalized (0 = random's
mean return, 1 = 150). The suite's reward is the row marked "shipped": the widest
margin of PD over stand with stand at most 0.4 on every velocity-commanded task.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

import bbbench
from bbbench.policies import load_policy
from bbbench.tasks.reward import RewardWeights, StayUpReward

POLICIES = ("random", "stand", "pd")
SHIPPED = StayUpReward()
CANDIDATES = {
    "first reward (v0, -v1 terrain)": RewardWeights(),
    "share 0.15, no tail": dataclasses.replace(SHIPPED, upright_share=0.15, tail_share=0.0),
    "share 0.10, no tail": dataclasses.replace(SHIPPED, tail_share=0.0),
    "share 0.20, no tail": dataclasses.replace(SHIPPED, upright_share=0.20, tail_share=0.0),
    "share 0.15, no tail, width 0.35 m/s": dataclasses.replace(
        SHIPPED, upright_share=0.15, tail_share=0.0, velocity_width=0.35
    ),
    "share 0.10, tail 0.1 over 2 m/s (shipped)": SHIPPED,
    "share 0.10, tail 0.2 over 2 m/s": dataclasses.replace(SHIPPED, tail_share=0.2),
    "share 0.15, tail 0.1 over 2 m/s": dataclasses.replace(SHIPPED, upright_share=0.15),
    "share 0.10, tail 0.1 over 3 m/s": dataclasses.replace(SHIPPED, tail_width=3.0),
}


def record(task_id: str, policy_name: str, episodes: int) -> list[np.ndarray]:
    """Per bot-episode, an array of (pitch, velocity error) per step played."""
    task = bbbench.spec(task_id)
    actor = load_policy(policy_name).actor(task_id)
    runs = []
    for seed in task.eval_seeds[:episodes]:
        rng = np.random.default_rng(seed)
        rngs = [rng] * (task.group.n_bots if task.multi_agent else 1)
        if task.multi_agent:
            env = bbbench.make_parallel(task_id)
            observations, _ = env.reset(seed=seed)
            steps = {agent: [] for agent in env.agents}
            while env.agents:
                batch = np.stack([observations[agent] for agent in env.agents])
                actions = actor(batch, rngs[: len(batch)])
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
    return runs


def mean_return(reward, runs: list[np.ndarray]) -> float:
    return float(
        np.mean([sum(sum(reward.terms(pitch, error)) for pitch, error in run) for run in runs])
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    args = parser.parse_args()
    tasks = bbbench.list_tasks(latest=True)
    recorded = {
        task_id: {name: record(task_id, name, args.episodes) for name in POLICIES}
        for task_id in tasks
    }
    names = [task_id.removeprefix("bbbench/") for task_id in tasks]
    print("| reward | " + " | ".join(names) + " |")
    print("|---|" + "---:|" * len(names))
    for label, reward in CANDIDATES.items():
        cells = []
        for task_id in tasks:
            returns = {name: mean_return(reward, recorded[task_id][name]) for name in POLICIES}
            best = reward.max_step * bbbench.spec(task_id).max_episode_steps
            stand, pd = (
                (returns[name] - returns["random"]) / (best - returns["random"])
                for name in ("stand", "pd")
            )
            cells.append(f"{stand:.3f} / {pd:.3f}")
        print(f"| {label} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()

"""Multi-bot benchmark: bot-steps per second in one world against FlatBalance-v0's steps.

    python bench/bench_multi.py [--bots 8] [--steps 6000] [--chunk 250] [--adapters]

Every bot is driven by the PD baseline (on its first five observations) on the
tasks' evaluation seeds, a world resetting when its episode ends. Only the
env's own calls are timed (`step`, and `reset` in the "with resets" column),
and the tasks run alternately in chunks so they share the machine's slow and
fast phases. A multi-bot world-step counts one bot-step per live bot.

`--adapters` also times the SB3 route: bbbench's `BotSlotsVecEnv` against
SuperSuit 3.11.0's `black_death_v3` + `pettingzoo_env_to_vec_env_v1` +
`concat_vec_envs_v1` (if SuperSuit is installed), on the same worlds.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import bbbench
from bbbench.policies import PDController

REFERENCE = "bbbench/FlatBalance-v0"
MULTI_TASKS = ("bbbench/MultiBalance-v0", "bbbench/MultiBumps-v0")


class SingleLoop:
    """The reference: one single-bot env, one bot-step per step."""

    def __init__(self, task_id: str) -> None:
        self.name = task_id
        self.env = bbbench.make(task_id)
        self.policy = PDController()
        self.seeds = iter(bbbench.spec(task_id).eval_seeds * 100)
        self.stepping = self.resetting = 0.0
        self.bot_steps = self.world_steps = self.episodes = 0
        self.observation = self._reset()

    def _reset(self):
        began = time.perf_counter()
        observation, _ = self.env.reset(seed=next(self.seeds))
        self.resetting += time.perf_counter() - began
        self.episodes += 1
        return observation

    def run(self, steps: int) -> None:
        step, policy, observation = self.env.step, self.policy, self.observation
        for _ in range(steps):
            action = policy(observation)
            began = time.perf_counter()
            observation, _, terminated, truncated, _ = step(action)
            self.stepping += time.perf_counter() - began
            if terminated or truncated:
                observation = self._reset()
        self.observation = observation
        self.bot_steps += steps
        self.world_steps += steps


class MultiLoop(SingleLoop):
    """One multi-bot world, every live bot under the PD baseline."""

    def __init__(self, task_id: str, n_bots: int) -> None:
        self.name = f"{task_id} x{n_bots}"
        self.env = bbbench.make_parallel(task_id, n_bots=n_bots)
        self.policy = PDController()
        self.seeds = iter(bbbench.spec(task_id).eval_seeds * 100)
        self.stepping = self.resetting = 0.0
        self.bot_steps = self.world_steps = self.episodes = 0
        self.observation = self._reset()

    def run(self, steps: int) -> None:
        env, policy, observations = self.env, self.policy, self.observation
        for _ in range(steps):
            actions = {agent: policy(observations[agent][:5]) for agent in env.agents}
            began = time.perf_counter()
            observations, *_ = env.step(actions)
            self.stepping += time.perf_counter() - began
            self.bot_steps += len(actions)
            if not env.agents:
                observations = self._reset()
        self.observation = observations
        self.world_steps += steps


def measure(loops, steps: int, chunk: int) -> None:
    for loop in loops:
        loop.run(chunk)  # warm up: worlds built, first terrains drawn
        loop.stepping = loop.resetting = 0.0
        loop.bot_steps = loop.world_steps = loop.episodes = 0
    done = 0
    while done < steps:
        for loop in loops:
            loop.run(chunk)
        done += chunk
    reference = loops[0]
    rate = reference.bot_steps / reference.stepping
    rate_reset = reference.bot_steps / (reference.stepping + reference.resetting)
    print(
        f"{'task':34s} {'world-steps/s':>13s} {'bots/step':>9s} {'bot-steps/s':>11s} "
        f"{'ratio':>6s} {'with resets':>11s} {'episodes':>8s}"
    )
    for loop in loops:
        bot_rate = loop.bot_steps / loop.stepping
        with_resets = loop.bot_steps / (loop.stepping + loop.resetting)
        print(
            f"{loop.name:34s} {loop.world_steps / loop.stepping:13.0f} "
            f"{loop.bot_steps / loop.world_steps:9.2f} {bot_rate:11.0f} "
            f"{bot_rate / rate:6.3f} {with_resets / rate_reset:11.3f} {loop.episodes:8d}"
        )


def adapter_rate(vec, steps: int, seed: int = 0) -> float:
    """Slot-steps per second of an SB3 VecEnv under random actions."""
    rng = np.random.default_rng(seed)
    vec.reset()
    actions = rng.integers(0, 9, size=(steps, vec.num_envs))
    began = time.perf_counter()
    for row in actions:
        vec.step(row)
    return steps * vec.num_envs / (time.perf_counter() - began)


def supersuit_vec(task_id: str, n_envs: int, n_bots: int):
    import supersuit

    env = supersuit.black_death_v3(bbbench.make_parallel(task_id, n_bots=n_bots))
    vec = supersuit.pettingzoo_env_to_vec_env_v1(env)
    return supersuit.concat_vec_envs_v1(vec, n_envs, num_cpus=0, base_class="stable_baselines3")


def compare_adapters(n_bots: int, steps: int) -> None:
    task = MULTI_TASKS[0]
    rows = [("bbbench BotSlotsVecEnv", lambda: bbbench.make_vec(task, n_envs=2, n_bots=n_bots))]
    try:
        import supersuit  # noqa: F401
    except ImportError:
        print("SuperSuit is not installed: only bbbench's adapter is timed")
    else:
        rows.append(("SuperSuit 3.11.0 route", lambda: supersuit_vec(task, 2, n_bots)))
    print(f"\nSB3 VecEnv of 2 worlds x {n_bots} bots, random actions, {steps} steps each:")
    rates = {}
    for _ in range(2):  # alternate, keep the best of two
        for name, build in rows:
            rates[name] = max(rates.get(name, 0.0), adapter_rate(build(), steps))
    for name, rate in rates.items():
        print(f"  {name:24s} {rate:8.0f} slot-steps/s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bots", type=int, default=8)
    parser.add_argument("--steps", type=int, default=6000, help="world-steps per task")
    parser.add_argument("--chunk", type=int, default=250)
    parser.add_argument("--adapters", action="store_true")
    args = parser.parse_args()
    loops = [SingleLoop(REFERENCE), *(MultiLoop(task, args.bots) for task in MULTI_TASKS)]
    measure(loops, args.steps, args.chunk)
    if args.adapters:
        compare_adapters(args.bots, 1500)


if __name__ == "__main__":
    main()

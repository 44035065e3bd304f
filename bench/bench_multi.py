"""Multi-bot benchmark: bot-steps per second in one world against FlatBalance-v0's steps.

    python bench/bench_multi.py [--bots 8] [--steps 6000] [--chunk 250] [--adapters] [--ceiling]

Every bot is driven by the PD baseline (on its first five observations) on the
tasks' evaluation seeds, a world resetting when its episode ends. Only the
env's own calls are timed (`step`, and `reset` in the "with resets" column),
and the tasks run alternately in chunks so they share the machine's slow and
fast phases. A multi-bot world-step counts one bot-step per live bot.

`--ceiling` also times, in the same alternation, what pybullet alone charges per
bot-step in one world (`RawWorldLoop`: every bot's motor command, one
`stepSimulation`, the three reads of every bot and its rotation matrix, with no
other Python), the most a multi-bot env could reach against FlatBalance-v0, and
(`ApiFloorLoop`) the same plus the least a PettingZoo step must build and return
(an observation row per bot from its raw reads, the array, the five dicts).

`--adapters` also times the SB3 route: bbbench's `BotSlotsVecEnv` against
SuperSuit 3.11.0's `black_death_v3` + `pettingzoo_env_to_vec_env_v1` +
`concat_vec_envs_v1` (if SuperSuit is installed), on the same worlds.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pybullet
from bench_suite import REFERENCE, TaskLoop  # the same single-bot loop as the suite's bench

import bbbench
from bbbench.policies import PDController
from bbbench.robots import MODEL

MULTI_TASKS = ("bbbench/MultiBalance-v0", "bbbench/MultiBumps-v0")


class MultiLoop:
    """One multi-bot world, every live bot under the PD baseline; timed as `TaskLoop`."""

    def __init__(self, task_id: str, n_bots: int) -> None:
        self.name = f"{task_id} x{n_bots}"
        self.env = bbbench.make_parallel(task_id, n_bots=n_bots)
        self.policy = PDController()
        self.seeds = iter(bbbench.spec(task_id).eval_seeds * 100)
        self.elapsed = self.stepping = 0.0  # step and reset; step only
        self.steps = self.bot_steps = self.episodes = 0  # world-steps; live bots stepped
        self.observation = self._reset()

    def _reset(self):
        began = time.perf_counter()
        observations, _ = self.env.reset(seed=next(self.seeds))
        self.elapsed += time.perf_counter() - began
        self.episodes += 1
        return observations

    def run(self, steps: int) -> None:
        env, policy, observations = self.env, self.policy, self.observation
        for _ in range(steps):
            actions = {agent: policy(observations[agent][:5]) for agent in env.agents}
            began = time.perf_counter()
            observations, *_ = env.step(actions)
            took = time.perf_counter() - began
            self.elapsed += took
            self.stepping += took
            self.bot_steps += len(actions)
            if not env.agents:
                observations = self._reset()
        self.observation = observations
        self.steps += steps


class RawWorldLoop:
    """The pybullet calls of a multi-bot world-step and nothing else: the ceiling.

    The bots start as the env starts them (MultiBalance-v0's evaluation seeds) and
    hold a small constant wheel command; the world restarts every 500 steps.
    """

    def __init__(self, n_bots: int) -> None:
        self.name = f"pybullet alone x{n_bots}"
        self.env = bbbench.make_parallel(MULTI_TASKS[0], n_bots=n_bots)
        self.seeds = iter(bbbench.spec(MULTI_TASKS[0]).eval_seeds * 100)
        self.env.reset(seed=next(self.seeds))
        scene = self.env.scene
        self.bots = [(bot.body, bot.wheel_joints) for bot in scene.bots]
        self.client_id = scene.world.client_id
        self.forces = (MODEL.motor_torque_limit,) * 2
        self.elapsed = self.stepping = 0.0
        self.steps = self.bot_steps = self.episodes = 0

    def run(self, steps: int) -> None:
        for _ in range(steps):
            began = time.perf_counter()
            self._drive()
            self._read()
            took = time.perf_counter() - began
            self.elapsed += took
            self.stepping += took
            self.bot_steps += len(self.bots)
            self.steps += 1
            if self.steps % 500 == 0:
                self.env.reset(seed=next(self.seeds))
                self.episodes += 1

    def _drive(self) -> None:
        """Every bot's motor command, then one world step."""
        cid, forces = self.client_id, self.forces
        for body, joints in self.bots:
            pybullet.setJointMotorControlArray(
                body,
                joints,
                pybullet.VELOCITY_CONTROL,
                targetVelocities=(0.5, -0.5),
                forces=forces,
                physicsClientId=cid,
            )
        pybullet.stepSimulation(cid)

    def _read(self) -> None:
        """Every bot's three reads and its rotation matrix."""
        cid = self.client_id
        for body, joints in self.bots:
            _, orientation = pybullet.getBasePositionAndOrientation(body, cid)
            pybullet.getBaseVelocity(body, cid)
            pybullet.getJointStates(body, joints, cid)
            pybullet.getMatrixFromQuaternion(orientation)


class ApiFloorLoop(RawWorldLoop):
    """`RawWorldLoop` plus the least a PettingZoo step must hand back: the pybullet
    calls, then an observation row per bot from its raw reads (no arithmetic), the
    rows as one array, and the five per-agent dicts (an info of three terms each).

    What any multi-bot env in Python pays per bot-step before it computes anything.
    """

    def __init__(self, n_bots: int) -> None:
        super().__init__(n_bots)
        self.name = f"API floor x{n_bots}"
        self.agents = list(self.env.possible_agents)
        self.pad = [0.0] * 12  # the neighbour part of a row

    def _read(self) -> None:
        cid, agents, pad = self.client_id, self.agents, self.pad
        rows, rewards, terminations, infos = [], {}, {}, {}
        for agent, (body, joints) in zip(agents, self.bots, strict=True):
            position, orientation = pybullet.getBasePositionAndOrientation(body, cid)
            velocity, spin = pybullet.getBaseVelocity(body, cid)
            left, right = pybullet.getJointStates(body, joints, cid)
            pybullet.getMatrixFromQuaternion(orientation)
            rows.append([orientation[0], spin[0], left[1], right[1], velocity[0], *pad])
            rewards[agent] = position[2]
            terminations[agent] = False
            infos[agent] = {"a": position[0], "b": position[1], "c": velocity[1]}
        observations = np.array(rows, dtype=np.float32)
        dict(zip(agents, observations, strict=True))
        dict.fromkeys(agents, False)


def measure(loops, steps: int, chunk: int) -> None:
    for loop in loops:
        loop.run(chunk)  # warm up: worlds built, first terrains drawn
        loop.elapsed = loop.stepping = 0.0
        loop.steps = loop.episodes = 0
        loop.bot_steps = 0  # a single-bot TaskLoop's bot-steps are its steps
    for _ in range(0, steps, chunk):
        for loop in loops:
            loop.run(chunk)
    bot_steps = [loop.bot_steps or loop.steps for loop in loops]
    rate = bot_steps[0] / loops[0].stepping
    rate_reset = bot_steps[0] / loops[0].elapsed
    print(
        f"{'task':34s} {'world-steps/s':>13s} {'bots/step':>9s} {'bot-steps/s':>11s} "
        f"{'ratio':>6s} {'with resets':>11s} {'episodes':>8s}"
    )
    for loop, bots in zip(loops, bot_steps, strict=True):
        name = getattr(loop, "name", REFERENCE)
        bot_rate = bots / loop.stepping
        print(
            f"{name:34s} {loop.steps / loop.stepping:13.0f} {bots / loop.steps:9.2f} "
            f"{bot_rate:11.0f} {bot_rate / rate:6.3f} "
            f"{bots / loop.elapsed / rate_reset:11.3f} {loop.episodes:8d}"
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
    parser.add_argument("--ceiling", action="store_true", help="also time pybullet alone")
    args = parser.parse_args()
    loops = [TaskLoop(REFERENCE), *(MultiLoop(task, args.bots) for task in MULTI_TASKS)]
    if args.ceiling:
        loops += [RawWorldLoop(args.bots), ApiFloorLoop(args.bots)]
    measure(loops, args.steps, args.chunk)
    if args.adapters:
        compare_adapters(args.bots, 1500)


if __name__ == "__main__":
    main()

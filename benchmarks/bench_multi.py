"""Multi-bot benchmark: bot-steps per second in one world against FlatBalance-v0's steps.

    python benchmarks/bench_multi.py [--bots 8] [--steps 6000] [--chunk 250] [--adapters]
                                     [--ceiling] [--vectorized]

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

`--vectorized` times the neighbour part of the observation two ways on the same
recorded world-steps (the bots' states, commands and targets of MultiBalance-v0
episodes under PD): the shipped plain-Python `group_observations`, and one
vectorised numpy pass over every bot (`numpy_group_observations`, limited to
exactly rounded operations so that it gives the same bytes, which is checked).

`--adapters` also times the SB3 route: bbbench's `BotSlotsVecEnv` against
SuperSuit 3.11.0's `black_death_v3` + `pettingzoo_env_to_vec_env_v1` +
`concat_vec_envs_v1` (if SuperSuit is installed), on the same worlds.
"""

from __future__ import annotations

import argparse
import functools
import itertools
import time

import numpy as np
import pybullet
from bench_suite import REFERENCE, TaskLoop  # the same single-bot loop as the suite's bench

import bbbench
from bbbench.policies import PDController
from bbbench.robots import MODEL
from bbbench.robots.layout import sensed
from bbbench.tasks.group import NEIGHBOUR_SPEED_RANGE
from bbbench.tasks.observation import group_observations

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
        f"{'ratio':>6s} {'with resets':>11s} {'episodes':>8s} {'us/bot-step':>11s}"
    )
    for loop, bots in zip(loops, bot_steps, strict=True):
        name = getattr(loop, "name", REFERENCE)
        bot_rate = bots / loop.stepping
        print(
            f"{name:34s} {loop.steps / loop.stepping:13.0f} {bots / loop.steps:9.2f} "
            f"{bot_rate:11.0f} {bot_rate / rate:6.3f} "
            f"{bots / loop.elapsed / rate_reset:11.3f} {loop.episodes:8d} "
            f"{1e6 / bot_rate:11.2f}"
        )


def record_steps(n_bots: int, steps: int) -> list[tuple]:
    """`steps` world-steps of MultiBalance-v0 under PD: each one's live states, wheel
    commands, targets and the observations the env returned."""
    env = bbbench.make_parallel(MULTI_TASKS[0], n_bots=n_bots)
    policy, seeds = PDController(), iter(bbbench.spec(MULTI_TASKS[0]).eval_seeds)
    scene, recorded = env.scene, []
    observations, _ = env.reset(seed=next(seeds))
    while len(recorded) < steps:
        live = len(env.agents)
        observations, *_ = env.step({a: policy(observations[a][:5]) for a in env.agents})
        bots = scene.live_bots
        if len(bots) == live:  # no bot left this step: the ones it observed are still here
            states = [bot.read() for bot in bots]  # a read is a query: the step's own state
            commands = [bot.wheel_command for bot in bots]
            returned = np.array([observations[a] for a in env.agents])
            recorded.append((states, commands, scene.live_targets(scene.steps), returned))
        if not env.agents:
            observations, _ = env.reset(seed=next(seeds))
    env.close()
    return recorded


def numpy_group_observations(states, commands, targets, group, size) -> np.ndarray:
    """`group_observations` as one vectorised numpy pass over every bot and neighbour.

    The same bytes: only exactly rounded operations (+ - * and comparisons) on float64
    columns, the nearest-neighbour order from the same numpy distances, and Python's
    `abs` for the range test of the rare offset within 1e-12 of the range.
    """
    n, k, reach, top = len(states), group.neighbours, group.neighbour_range, NEIGHBOUR_SPEED_RANGE
    points = np.array([complex(s.position[0], s.position[1]) for s in states])
    moving = np.array([complex(*s.velocity) for s in states])
    heading = np.array([s.heading for s in states])
    pairs = points[None, :] - points[:, None]
    distance = np.abs(pairs)
    distance.flat[:: n + 1] = np.inf
    nearest = np.argsort(distance, axis=1, kind="stable")[:, : min(k, n - 1)]
    both = np.stack([np.take_along_axis(pairs, nearest, 1), moving[nearest] - moving[:, None]])
    forward_x, forward_y = heading[:, 0:1], heading[:, 1:2]
    right = both.real * forward_y - both.imag * forward_x  # (x + iy) * (fy + i fx)
    ahead = both.real * forward_x + both.imag * forward_y
    squared = right[0] * right[0] + ahead[0] * ahead[0]
    near = squared < reach * reach * (1 - 1e-12)
    for i, j in zip(*np.nonzero(~near & (squared <= reach * reach * (1 + 1e-12))), strict=True):
        near[i, j] = abs(complex(right[0, i, j], ahead[0, i, j])) <= reach
    near = np.logical_and.accumulate(near, axis=1)  # the rest are farther
    block = np.stack([right[0], ahead[0], *np.clip((right[1], ahead[1]), -top, top)], axis=-1)
    block[~near] = 0.0
    rows = np.zeros((n, size), dtype=np.float32)
    rows[:, :5] = [
        (*sensed(s.pitch, s.pitch_rate, s.wheel_speed), c, t)
        for s, c, t in zip(states, commands, targets, strict=True)
    ]
    rows[:, 5 : 5 + block.shape[1] * 4] = block.reshape(n, -1)
    return rows


def compare_neighbour_passes(n_bots: int, steps: int, rounds: int = 5) -> None:
    recorded = record_steps(n_bots, steps)
    env = bbbench.make_parallel(MULTI_TASKS[0], n_bots=n_bots)
    group, size = env.task.group, env.observation_space(env.possible_agents[0]).shape[0]
    robot = env.task.robot_model
    passes = {
        "plain Python (shipped)": functools.partial(group_observations, robot),
        "numpy, one pass": numpy_group_observations,
    }
    elapsed = dict.fromkeys(passes, 0.0)
    bots = sum(len(states) for states, *_ in recorded)
    for states, commands, targets, returned in recorded:
        for name, build in passes.items():
            if build(states, commands, targets, group, size).tobytes() != returned.tobytes():
                raise SystemExit(f"{name}: not the observations the env returned")
    for _, (name, build) in itertools.product(range(rounds), passes.items()):
        began = time.perf_counter()
        for states, commands, targets, _ in recorded:
            build(states, commands, targets, group, size)
        elapsed[name] += time.perf_counter() - began
    print(
        f"\nObservations with neighbours, {len(recorded)} recorded world-steps x {rounds}, "
        f"{bots / len(recorded):.2f} bots a step (bytes equal to the env's):"
    )
    for name, took in elapsed.items():
        per_step = took / (rounds * len(recorded)) * 1e6
        per_bot = took / (rounds * bots) * 1e6
        print(f"  {name:24s} {per_step:7.2f} us a world-step {per_bot:6.2f} us a bot")


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
    parser.add_argument("--vectorized", action="store_true", help="time a numpy neighbour pass")
    args = parser.parse_args()
    loops = [TaskLoop(REFERENCE), *(MultiLoop(task, args.bots) for task in MULTI_TASKS)]
    if args.ceiling:
        loops += [RawWorldLoop(args.bots), ApiFloorLoop(args.bots)]
    measure(loops, args.steps, args.chunk)
    if args.vectorized:
        compare_neighbour_passes(args.bots, min(args.steps, 2000))
    if args.adapters:
        compare_adapters(args.bots, 1500)


if __name__ == "__main__":
    main()

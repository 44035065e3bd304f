"""Robot benchmark: the wheel-legged robot's step and reset against the two-wheel bot's.

    python benchmarks/bench_robots.py [--steps 20000] [--chunk 250] [--resets 60]

Each wheel-legged task is timed beside the same spec played by the two-wheel bot (its
row with `robot="two-wheel"`: the same ground, seeds and targets), each robot under its
classical controller (the legged controller; PD), in alternating chunks so that both
share the machine's slow and fast phases. Reported, env time only:

- step: the mean time of `env.step` (the policy excluded), and its ratio to a
  FlatBalance-v1 step of the two-wheel bot (target: <= 2.5x);
- reset: the mean time of `env.reset(seed=s)` on fresh seeds, which on terrain draws and
  loads a new heightfield, and its ratio to the two-wheel bot's on the same task
  (target: <= 1.2x).

Then where a step's time goes: the world's step against the rest, and a profile of the
rest of a wheel-legged step.
"""

from __future__ import annotations

import argparse
import cProfile
import dataclasses
import pstats
import statistics
import time

from bench_suite import TaskLoop  # one task's timed loop, as the suite's bench has it

import bbbench

REFERENCE = "bbbench/FlatBalance-v1"
LEGGED = (
    "bbbench/LeggedFlatBalance-v0",
    "bbbench/LeggedVelocityTracking-v0",
    "bbbench/LeggedBumps-v0",
    "bbbench/LeggedObstacles-v0",
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=20_000, help="steps per task and robot")
    parser.add_argument("--chunk", type=int, default=250, help="steps per alternation")
    parser.add_argument("--resets", type=int, default=60, help="extra resets per task and robot")
    args = parser.parse_args()

    loops = {("two-wheel", REFERENCE): TaskLoop(bbbench.spec(REFERENCE))}
    for task_id in LEGGED:
        task = bbbench.spec(task_id)
        loops["wheel-legged", task_id] = TaskLoop(task)
        loops["two-wheel", task_id] = TaskLoop(dataclasses.replace(task, robot="two-wheel"))
    for _ in range(0, args.steps, args.chunk):
        for loop in loops.values():
            loop.run(args.chunk)
    for _ in range(args.resets):  # resets alone, alternating too
        for loop in loops.values():
            loop.reset()
    flat = loops["two-wheel", REFERENCE].step_time

    print(
        f"Robot benchmark: {args.steps} steps per task and robot under its classical "
        f"controller, alternating every {args.chunk} steps, then {args.resets} resets each"
    )
    print(
        f"  {'task':34s} {'robot':13s} {'step us':>8s} {'x Flat':>7s} {'reset ms':>9s} "
        f"{'x two-wheel':>12s}"
    )
    for (robot, task_id), loop in loops.items():
        reset = statistics.fmean(loop.reset_times[1:])
        versus = ""
        if robot == "wheel-legged":
            other = statistics.fmean(loops["two-wheel", task_id].reset_times[1:])
            versus = f"{reset / other:12.3f}"
        print(
            f"  {task_id:34s} {robot:13s} {1e6 * loop.step_time:8.1f} "
            f"{loop.step_time / flat:7.3f} {1e3 * reset:9.2f} {versus}"
        )
    print("  targets: a wheel-legged step <= 2.5x FlatBalance-v1's; its reset <= 1.2x")

    print("\nWhere a step's time goes: the world's step (physics) and the rest (Python), us")
    for robot, task_id in (("two-wheel", REFERENCE), *(("wheel-legged", t) for t in LEGGED)):
        physics, total = split(loops[robot, task_id], 5000)
        print(f"  {task_id:34s} {robot:13s} physics {physics:6.1f}  rest {total - physics:6.1f}")
    loop = loops["wheel-legged", "bbbench/LeggedBumps-v0"]
    print("\nThe rest of a wheel-legged step (LeggedBumps-v0, cProfile of env.step, tottime):")
    profiler = cProfile.Profile()
    steps_only(loop, 5000, profiler)
    stats = pstats.Stats(profiler)
    total = sum(row[2] for row in stats.stats.values())
    rows = sorted(stats.stats.items(), key=lambda item: -item[1][2])[:10]
    for (path, _line, name), (_, calls, tottime, *_rest) in rows:
        where = name if path == "~" else f"{path.rsplit('/', 1)[-1]}:{name}"
        print(f"  {100 * tottime / total:5.1f}%  {calls:>7d} calls  {where}")


def split(loop: TaskLoop, steps: int) -> tuple[float, float]:
    """Mean microseconds per env step: in the world's step, and in all."""
    scene = loop.env.unwrapped.scene
    world = scene.world
    world_step, spent = world.step, [0.0]

    def timed() -> None:
        began = time.perf_counter()
        world_step()
        spent[0] += time.perf_counter() - began

    # The scene binds the world's step when it builds the world: rebuild it, timed.
    world.step = timed
    scene.close()
    loop.observation = loop.reset()
    before, stepped = loop.stepping, loop.steps
    loop.run(steps)
    del world.step
    scene.close()
    loop.observation = loop.reset()
    return 1e6 * spent[0] / steps, 1e6 * (loop.stepping - before) / (loop.steps - stepped)


def steps_only(loop: TaskLoop, steps: int, profiler: cProfile.Profile) -> None:
    """`steps` env steps under the controller, the profiler on for `env.step` alone."""
    step, policy, observation = loop.env.step, loop.policy, loop.observation
    for _ in range(steps):
        action = policy(observation)
        profiler.enable()
        observation, _, terminated, truncated, _ = step(action)
        profiler.disable()
        if terminated or truncated:
            observation = loop.reset()
    loop.observation = observation


if __name__ == "__main__":
    main()

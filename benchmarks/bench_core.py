"""Core benchmark: FlatBalance-v0 against a raw pybullet loop doing the same physics.

    python benchmarks/bench_core.py [--steps 100000] [--chunk 250]

Prints ratios measured in one run (the machine is shared and noisy; only
ratios between loops measured side by side mean anything):

- env step rate / raw pybullet step rate, through `gym.make` (all default
  wrappers), resets included. The raw loop replays the very same episodes:
  same seeded initial leans, same actions, same pybullet calls (motor command,
  stepSimulation, base pose, base velocity, joint states) and repositions the
  bot where the env resets it. The run checks that both loops end in the same
  physical state, so the ratio compares equal physics work.
- what the shared reward in which staying up never costs adds to a step: FlatBalance-v1
  (`StayUpReward`) against FlatBalance-v0 (the first reward) on the same episodes,
  interleaved with the others (target: at most 2% of a FlatBalance step), and the two
  rewards' own cost per call, timed alone, as a share of that step;
- mean `env.reset()` time on flat ground (reposition, no reload);
- Gymnasium's InvertedPendulum-v5 (MuJoCo) step rate, as an outside reference
  (needs the `bench` extra: pip install -c constraints.txt ".[bench]").
"""

from __future__ import annotations

import argparse
import statistics
import time

import gymnasium as gym
import numpy as np
import pybullet

import bbbench
from bbbench.robots import FALL_TILT, MODEL
from bbbench.robots.balancebot import spawn_pose, tilt_from_quaternion
from bbbench.robots.body import WHEEL_CONTACT_PROCESSING_THRESHOLD
from bbbench.robots.twowheel import WHEEL_SPEED_CHANGES
from bbbench.sim import GRAVITY, physics_parameters
from bbbench.tasks.reward import RewardWeights, StayUpReward, step_outcome
from bbbench.tasks.spec import TRAINING_SEEDS, seed_streams
from bbbench.terrain import GROUND_FRICTION

TASK = "bbbench/FlatBalance-v0"
NEW_REWARD_TASK = "bbbench/FlatBalance-v1"  # the same episodes, the new shared reward
SEED = 0


def random_actions(steps: int) -> list[int]:
    rng = np.random.default_rng(12345)
    return [int(a) for a in rng.integers(0, len(WHEEL_SPEED_CHANGES), size=steps)]


class EnvLoop:
    """A task (FlatBalance-v0) through gym.make (all default wrappers), resetting as
    episodes end."""

    def __init__(self, task: str = TASK) -> None:
        self.env = gym.make(task)
        self.env.reset(seed=SEED)
        self.episodes = 1

    def run(self, actions: list[int]) -> None:
        step, reset = self.env.step, self.env.reset
        for action in actions:
            _, _, terminated, truncated, _ = step(action)
            if terminated or truncated:
                reset()
                self.episodes += 1

    def pose(self) -> tuple:
        bot = self.env.unwrapped.scene.bots[0]
        return pybullet.getBasePositionAndOrientation(bot.body, bot.client_id)

    def close(self) -> None:
        self.env.close()


class RawLoop:
    """The same episodes in plain pybullet calls: what the env's physics costs by itself.

    Same world settings, ground and URDF; per step the calls the env needs
    (motor command, stepSimulation, base pose, base velocity, joint states);
    the bot is repositioned, with the same seeded lean, where the env resets.
    """

    def __init__(self) -> None:
        spec = bbbench.spec(TASK)
        self.max_steps = spec.max_episode_steps
        self.initial_pitch = spec.initial_pitch
        self.cid = cid = pybullet.connect(pybullet.DIRECT)
        pybullet.setGravity(0.0, 0.0, -GRAVITY, physicsClientId=cid)
        pybullet.setPhysicsEngineParameter(
            fixedTimeStep=spec.control_dt,
            numSubSteps=spec.physics_substeps,
            physicsClientId=cid,
            **physics_parameters(),
        )
        plane = pybullet.createCollisionShape(pybullet.GEOM_PLANE, physicsClientId=cid)
        ground = pybullet.createMultiBody(0.0, plane, physicsClientId=cid)
        pybullet.changeDynamics(ground, -1, lateralFriction=GROUND_FRICTION, physicsClientId=cid)
        self.body = pybullet.loadURDF(
            str(MODEL.urdf_path), flags=pybullet.URDF_USE_INERTIA_FROM_FILE, physicsClientId=cid
        )
        self.joints = (0, 1)
        for joint in self.joints:  # the robot's contact setting, as BalanceBot applies it
            pybullet.changeDynamics(
                self.body,
                joint,
                contactProcessingThreshold=WHEEL_CONTACT_PROCESSING_THRESHOLD,
                physicsClientId=cid,
            )
        self.forces = (MODEL.motor_torque_limit,) * 2
        self.np_random = np.random.default_rng(SEED)  # what gymnasium's reset(seed=SEED) seeds
        self.episodes = 0
        self.reset()

    def reset(self) -> None:
        cid, body = self.cid, self.body
        # The env's episode seeds: SEED first, then training seeds drawn from np_random.
        episode_seed = int(self.np_random.integers(TRAINING_SEEDS.stop)) if self.episodes else SEED
        start = seed_streams(episode_seed).start
        pitch = float(start.uniform(-self.initial_pitch, self.initial_pitch))
        com, orientation = spawn_pose(pitch)  # the pose BalanceBot.reset gives the same lean
        # As BalanceBot.reset: drop the last episode's contact points (clear of everything,
        # collision detection), so the episode does not depend on the one before.
        far = (-1000.0, 10.0 * (1 + body), 10.0)
        pybullet.resetBasePositionAndOrientation(body, far, (0, 0, 0, 1), physicsClientId=cid)
        pybullet.performCollisionDetection(cid)
        pybullet.resetBasePositionAndOrientation(body, com, orientation, physicsClientId=cid)
        pybullet.resetBaseVelocity(body, (0, 0, 0), (0, 0, 0), physicsClientId=cid)
        for joint in self.joints:
            pybullet.resetJointState(body, joint, 0.0, 0.0, physicsClientId=cid)
        pybullet.setJointMotorControlArray(
            body,
            self.joints,
            pybullet.VELOCITY_CONTROL,
            targetVelocities=(0.0, 0.0),
            forces=self.forces,
            physicsClientId=cid,
        )
        self.command, self.steps = 0.0, 0
        self.episodes += 1

    def run(self, actions: list[int]) -> None:
        cid, body, joints, forces = self.cid, self.body, self.joints, self.forces
        limit, changes = MODEL.wheel_speed_limit, WHEEL_SPEED_CHANGES
        command, steps = self.command, self.steps
        for action in actions:
            command = max(-limit, min(limit, command + changes[action]))
            pybullet.setJointMotorControlArray(
                body,
                joints,
                pybullet.VELOCITY_CONTROL,
                targetVelocities=(command, -command),
                forces=forces,
                physicsClientId=cid,
            )
            pybullet.stepSimulation(cid)  # positional client ids: pybullet's fastest form
            _, orientation = pybullet.getBasePositionAndOrientation(body, cid)
            pybullet.getBaseVelocity(body, cid)
            pybullet.getJointStates(body, joints, cid)
            steps += 1
            # The env's own fall test, so both loops end episodes on the same step.
            if tilt_from_quaternion(orientation) > FALL_TILT or steps == self.max_steps:
                self.reset()
                command, steps = 0.0, 0
        self.command, self.steps = command, steps

    def pose(self) -> tuple:
        return pybullet.getBasePositionAndOrientation(self.body, self.cid)

    def close(self) -> None:
        pybullet.disconnect(self.cid)


def interleaved(loops: dict, actions: list[int], chunk: int) -> dict[str, float]:
    """Run every loop over `actions`, alternating in chunks; total seconds per loop.

    Short alternating chunks make the loops share the machine's slow and fast
    phases, so their ratio is steady even when absolute rates are not.
    """
    totals = dict.fromkeys(loops, 0.0)
    for start in range(0, len(actions), chunk):
        part = actions[start : start + chunk]
        for name, loop in loops.items():
            began = time.perf_counter()
            loop.run(part)
            totals[name] += time.perf_counter() - began
    return totals


def reward_call_time(reward, calls: int = 200_000) -> float:
    """Seconds per `step_outcome` call with `reward`, on a recorded state (min of 5)."""
    env = gym.make(TASK)
    env.reset(seed=SEED)
    state = env.unwrapped.scene.bots[0].read()
    env.close()
    best = float("inf")
    for _ in range(5):
        began = time.perf_counter()
        for _ in range(calls):
            step_outcome(state, 0.3, reward)
        best = min(best, time.perf_counter() - began)
    return best / calls


def reset_time(resets: int) -> float:
    """Mean seconds per env.reset() through gym.make, world already built."""
    env = gym.make(TASK)
    env.reset(seed=SEED)
    start = time.perf_counter()
    for _ in range(resets):
        env.reset()
    elapsed = time.perf_counter() - start
    env.close()
    return elapsed / resets


def mujoco_rate(steps: int) -> float | None:
    """InvertedPendulum-v5 steps per second with random actions, resets included."""
    try:
        env = gym.make("InvertedPendulum-v5")
    except (ImportError, gym.error.DependencyNotInstalled):
        return None
    env.reset(seed=SEED)
    env.action_space.seed(SEED)
    actions = [env.action_space.sample() for _ in range(steps)]
    start = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    elapsed = time.perf_counter() - start
    env.close()
    return steps / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=100_000, help="steps per loop")
    parser.add_argument("--chunk", type=int, default=250, help="steps per alternation")
    parser.add_argument("--resets", type=int, default=2_000, help="resets to time")
    args = parser.parse_args()

    actions = random_actions(args.steps)
    loops = {"raw": RawLoop(), "env": EnvLoop(), "env-v1": EnvLoop(NEW_REWARD_TASK)}
    totals = interleaved(loops, actions, args.chunk)
    same = loops["raw"].episodes == loops["env"].episodes and (
        loops["raw"].pose() == loops["env"].pose()
    )
    episodes = loops["env"].episodes
    for loop in loops.values():
        loop.close()
    raw_rate, env_rate = args.steps / totals["raw"], args.steps / totals["env"]
    step_us = 1e6 * totals["env"] / args.steps
    first_us, new_us = (
        1e6 * reward_call_time(reward) for reward in (RewardWeights(), StayUpReward())
    )
    reset_ms = 1e3 * statistics.median(reset_time(args.resets) for _ in range(3))
    ip_rate = mujoco_rate(min(args.steps, 20_000))

    print(
        f"FlatBalance-v0 core benchmark: {args.steps} random-action steps per loop, "
        f"alternating every {args.chunk} steps; {episodes} episodes"
    )
    print(f"  same physics in both loops (episodes and final pose equal): {same}")
    print(f"  raw pybullet loop              {raw_rate:10.0f} steps/s")
    print(f"  env.step via gym.make          {env_rate:10.0f} steps/s")
    print(f"  ratio env / raw                {env_rate / raw_rate:10.3f}   (target >= 0.85)")
    print(
        f"  FlatBalance-v1 / -v0 step time {totals['env-v1'] / totals['env']:10.3f}   "
        f"(the new reward's cost, same episodes; target <= 1.02)"
    )
    print(
        f"  step_outcome per call          {first_us:10.3f} us first reward, {new_us:.3f} us "
        f"StayUpReward: +{(new_us - first_us) / step_us:.1%} of a {step_us:.1f} us step"
    )
    print(f"  env.reset() on flat ground     {reset_ms:10.3f} ms mean  (target <= 1 ms)")
    if ip_rate is None:
        print(
            "  InvertedPendulum-v5 (MuJoCo)   not installed: pip install -c constraints.txt "
            '".[bench]"'
        )
    else:
        print(
            f"  InvertedPendulum-v5 (MuJoCo)   {ip_rate:10.0f} steps/s   "
            f"(ratio FlatBalance / InvertedPendulum {env_rate / ip_rate:.3f})"
        )
    if not same:
        raise SystemExit("the raw loop and the env did different physics: the ratio is not valid")


if __name__ == "__main__":
    main()

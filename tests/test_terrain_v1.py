"""The -v1 terrain tasks: hard for the PD baseline, not trivial, not impossible; the height
scan reads the ground the bot drives on."""

from __future__ import annotations

import ast
import dataclasses
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import bbbench
from bbbench.cli import main
from bbbench.policies import PDController
from bbbench.robots import TWO_WHEEL
from bbbench.robots.layout import SCAN_OFFSETS, SCAN_POINTS
from bbbench.terrain import Heightmap, Slopes
from bbbench.terrain import generators as generators_module

V1_TERRAIN = ["bbbench/Bumps-v1", "bbbench/Obstacles-v1", "bbbench/Slopes-v1"]
CALIBRATION_SEEDS = 24  # the first eval seeds; docs/tasks.md has all 100


def ground_under(env, x: float, y: float) -> tuple[int, float]:
    """(body, height) of what a ray cast down at (x, y) meets first, the bot left out."""
    top = 5.0
    while True:
        hit = env.scene.world.client.rayTest((x, y, top), (x, y, -5.0))[0]
        if hit[0] != env.scene.bots[0].body:
            return hit[0], hit[3][2]
        top = hit[3][2] - 1e-4  # on, from just under the bot


def pd_successes(task_id: str, seeds) -> list[bool]:
    env, policy = bbbench.make(task_id), PDController()
    outcomes = []
    for seed in seeds:
        observation, _ = env.reset(seed=seed)
        while True:
            observation, _, terminated, truncated, _ = env.step(policy(observation))
            if terminated or truncated:
                outcomes.append(not terminated)
                break
    env.close()
    return outcomes


@pytest.mark.parametrize("task_id", V1_TERRAIN)
def test_pd_finishes_only_some_episodes_at_the_default_difficulty(task_id):
    """The calibration: PD finishes 20-60% of all 100 eval seeds (docs/tasks.md); on the
    first 24 the band is wider, 10-75%. Terrain made trivial or impossible fails this."""
    seeds = bbbench.spec(task_id).eval_seeds[:CALIBRATION_SEEDS]
    success = np.mean(pd_successes(task_id, seeds))
    assert 0.10 <= success <= 0.75, f"{task_id}: PD finished {success:.0%} of {len(seeds)}"


@pytest.mark.parametrize("task_id", V1_TERRAIN)
def test_the_shipped_ppo_policy_finishes_more_episodes_than_pd(task_id):
    """Learning pays: the PPO policy trained on the task (docs/notebook.md) finishes at least
    15 points more of the first 16 eval seeds than PD does. Terrain made impossible, or
    easy enough for PD to finish everything, fails this."""
    from bbbench.evaluation import evaluate
    from bbbench.policies import load_policy

    trained = f"ppo-{task_id.split('/')[1].split('-')[0].lower()}-v1"
    success = {
        name: evaluate(load_policy(name), [task_id], episodes=16, workers=1).document["tasks"][0][
            "aggregate"
        ]["success_rate"]
        for name in (trained, "pd")
    }
    assert success[trained] >= success["pd"] + 0.15, success


@pytest.mark.parametrize("task_id", V1_TERRAIN)
def test_the_same_terrain_at_difficulty_0_is_easy_for_pd(task_id):
    """The difficulty knob is what makes it hard: at 0, PD finishes nearly every episode."""
    easy = bbbench.spec(task_id).with_difficulty(0.0)
    env, policy = bbbench.envs.balance.BalanceEnv(easy), PDController()
    finished = 0
    for seed in easy.eval_seeds[:8]:
        observation, _ = env.reset(seed=seed)
        for _ in range(easy.max_episode_steps):
            observation, _, terminated, _, _ = env.step(policy(observation))
            if terminated:
                break
        finished += not terminated
    assert finished >= 7


@pytest.mark.parametrize("task_id", V1_TERRAIN)
def test_the_random_policy_falls_almost_always(task_id):
    env = bbbench.make(task_id)
    env.action_space.seed(0)
    falls = 0
    for seed in bbbench.spec(task_id).eval_seeds[:20]:
        env.reset(seed=seed)
        while True:
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            if terminated or truncated:
                falls += terminated
                break
    assert falls >= 19


def test_v0_stays_registered_beside_v1_and_gymnasium_points_to_v1():
    for name in ("Bumps", "Obstacles"):
        old, new = bbbench.spec(f"bbbench/{name}-v0"), bbbench.spec(f"bbbench/{name}-v1")
        assert old.fingerprint != new.fingerprint
        with pytest.warns(DeprecationWarning, match=f"{name}-v0 is out of date"):
            assert gym.make(f"bbbench/{name}-v0").unwrapped.task.id == old.id
    assert "bbbench/Slopes-v1" in bbbench.list_tasks()


def test_steepest_slopes_follow_the_documented_design():
    """Bumps-v1 reaches ~21 deg at its default, Slopes-v1's ramps at most 0.5 rad x d,
    and Obstacles-v1's heights 0.6x the wheel radius at difficulty 1."""

    def steepest(spec, seeds=range(5)) -> float:
        angles = []
        for seed in seeds:
            heights = spec.terrain.generate(np.random.default_rng(seed)).heights
            gx, gy = np.gradient(heights, spec.terrain.cell_size)
            angles.append(math.degrees(math.atan(np.hypot(gx, gy).max())))
        return float(np.mean(angles))

    bumps = bbbench.spec("bbbench/Bumps-v1")
    assert 17 <= steepest(bumps) <= 26
    assert steepest(bumps.with_difficulty(0.0)) < 5
    slopes = Slopes(min_incline=0.0, extra_incline=0.5, max_height=2.0, ramp_length=(0.3, 1.5))
    assert bbbench.spec("bbbench/Slopes-v1").terrain.generator == slopes
    profile = slopes(np.random.default_rng(0), 1.0, (3, 400), 0.1)[0]
    grades = np.abs(np.diff(profile)) / 0.1
    assert grades.max() <= math.tan(0.5) + 1e-9
    assert grades.max() > math.tan(0.4)  # steep ramps do occur
    obstacles = bbbench.spec("bbbench/Obstacles-v1").terrain.generator
    assert obstacles.height_bounds(1.0) == (0.0, pytest.approx(0.6 * 0.1))
    assert obstacles.max_gap(1.0) == pytest.approx(0.3)


def test_terrain_generators_are_pure_numpy():
    """Nothing in the generators' module knows about bullet, trimesh, robots or tasks."""
    tree = ast.parse(Path(generators_module.__file__).read_text())
    imported = {
        alias.name.split(".")[0] if isinstance(node, ast.Import) else node.module
        for node in ast.walk(tree)
        if isinstance(node, ast.Import | ast.ImportFrom)
        for alias in node.names
    }
    assert imported <= {"__future__", "numpy", "bbbench", "bbbench.parameters"}


def test_terrain_command_exports_slopes_v1(tmp_path, capsys):
    out = tmp_path / "t.obj"
    assert main(["terrain", "--task", "bbbench/Slopes-v1", "--seed", "3", "--out", str(out)]) == 0
    assert "bbbench/Slopes-v1 (difficulty 0.9), episode seed 3" in capsys.readouterr().out
    import trimesh

    mesh = trimesh.load(out, process=False)
    assert mesh.vertices[:, 2].max() > 0.3  # the ramps are there


# -- terrain without a side edge ------------------------------------------------------


@pytest.mark.parametrize("task_id", V1_TERRAIN)
def test_v1_terrain_repeats_across_the_strip(task_id):
    terrain = bbbench.spec(task_id).terrain
    heights = terrain.generate(np.random.default_rng(5)).heights
    period = round(terrain.lateral_period / terrain.cell_size)
    assert heights.shape[0] == 2 * period + 1
    np.testing.assert_array_equal(heights[:period], heights[period : 2 * period])
    np.testing.assert_array_equal(heights[0], heights[-1])
    assert heights.std() > 0.005  # not flat: the repeat is of real terrain


def test_the_field_follows_a_drifting_bot_and_the_ground_under_it_stays():
    """PD on Bumps-v1 drifts sideways past the strip's first copy of the terrain: every
    step the bot stands on the heightfield, never the flat ground beyond its side."""
    env = bbbench.make("bbbench/Bumps-v1").unwrapped
    policy = PDController()
    terrain = env.task.terrain
    drifted = 0.0
    for seed in env.task.eval_seeds[:6]:
        observation, _ = env.reset(seed=seed)
        for _ in range(1500):
            observation, _, terminated, _, _ = env.step(policy(observation))
            x, y, _ = env.scene.bots[0].read().axle
            drifted = max(drifted, abs(x))
            if terminated or not terrain.bounds[2] < y < terrain.bounds[3]:
                break
            assert ground_under(env, x, y)[0] == env.scene.ground.body, (seed, x, y)
    assert drifted > 2 * terrain.lateral_period  # the field really moved


def test_periodic_terrain_needs_a_periodic_generator_and_matching_width():
    from bbbench.terrain import HeightfieldTerrain, Obstacles

    with pytest.raises(ValueError, match="cannot repeat along x"):
        HeightfieldTerrain(generator=Obstacles(), size=(3.2, 20.0), lateral_period=1.6)
    with pytest.raises(ValueError, match=r"size\[0\] must be 3.2"):
        HeightfieldTerrain(generator=Slopes(), size=(4.0, 20.0), lateral_period=1.6)


# -- the height scan -----------------------------------------------------------------


def ramp_heightmap() -> Heightmap:
    """A constructed ground: a plane rising along x and y, with a box on it."""
    xs, ys = np.arange(-10, 11) * 0.2, np.arange(-5, 51) * 0.2
    heights = 0.3 + 0.1 * xs[:, None] + 0.05 * ys[None, :]
    heights[12:14, 20:22] += 0.2
    return Heightmap(heights, 0.2, (-2.0, -1.0))


def test_heights_along_match_the_heightmap_at_its_nodes_and_between_them():
    heightmap = ramp_heightmap()
    xs, ys = heightmap.node_coordinates()
    # At nodes: exactly the stored heights.
    at_nodes = heightmap.heights_along(xs[12], ys[18], (0.0, 1.0), (0.0, 0.2, 0.4, 0.6))
    np.testing.assert_allclose(at_nodes, heightmap.heights[12, 18:22], atol=1e-12)
    # Between nodes on the plane (away from the box): the plane, to the grid's resolution
    # (the nearest node is at most half a cell away in x and in y).
    direction = (math.cos(0.4), math.sin(0.4))
    between = heightmap.heights_along(-1.33, 2.07, direction, SCAN_OFFSETS)
    expected = [
        0.3 + 0.1 * (-1.33 + d * direction[0]) + 0.05 * (2.07 + d * direction[1])
        for d in SCAN_OFFSETS
    ]
    np.testing.assert_allclose(between, expected, atol=0.1 * 0.1 + 0.05 * 0.1)
    # And exactly the nearest node's height.
    xs, ys = heightmap.node_coordinates()
    nearest = [
        heightmap.heights[
            np.abs(xs - (-1.33 + d * direction[0])).argmin(),
            np.abs(ys - (2.07 + d * direction[1])).argmin(),
        ]
        for d in SCAN_OFFSETS
    ]
    np.testing.assert_allclose(between, nearest, atol=1e-12)
    # Off the map: the flat ground around it.
    assert heightmap.heights_along(50.0, 50.0, (1.0, 0.0), (0.0, 1.0)) == [0.0, 0.0]


def test_the_scan_reads_the_ground_bullet_simulates():
    """Scan values against rays cast down onto the bullet heightfield at the same points:
    equal to the heightfield's resolution (bilinear vs its two triangles per cell)."""
    env = bbbench.make("bbbench/Bumps-v1", height_scan=True).unwrapped
    policy = PDController()
    observation, _ = env.reset(seed=bbbench.spec("bbbench/Bumps-v1").eval_seeds[0])
    checked = 0
    for step in range(400):
        observation, _, terminated, _, _ = env.step(policy(observation[:5]))
        if terminated:
            break
        if step % 20:
            continue
        state = env.scene.bots[0].read()
        x, y, axle_height = state.axle
        # The terrain repeats across: a point past the field's side is read from its copy
        # on the field (where the field will be when the bot gets there).
        period = env.task.terrain.lateral_period
        middle = env.scene.world.client.getBasePositionAndOrientation(env.scene.ground.body)[0][0]
        points = [(x + d * state.heading[0], y + d * state.heading[1]) for d in SCAN_OFFSETS]
        points = [(px - round((px - middle) / period) * period, py) for px, py in points]
        hits = [ground_under(env, px, py) for px, py in points]
        assert {body for body, _ in hits} == {env.scene.ground.body}
        ground = [height for _, height in hits]
        cell, steepest = 0.05, math.tan(math.radians(35))
        np.testing.assert_allclose(observation[5:] + axle_height, ground, atol=cell * steepest)
        checked += 1
    assert checked >= 10
    env.close()


def test_height_scan_is_an_option_recorded_in_the_spec_and_space():
    env = bbbench.make("bbbench/Obstacles-v1", height_scan=True)
    blind = bbbench.make("bbbench/Obstacles-v1")
    assert env.observation_space == TWO_WHEEL.observation_space(height_scan=True)
    assert env.observation_space.shape == (5 + SCAN_POINTS,)
    assert blind.observation_space.shape == (5,)
    scanned = env.unwrapped.task
    assert scanned.height_scan
    assert not blind.unwrapped.task.height_scan
    assert scanned.fingerprint != blind.unwrapped.task.fingerprint
    assert scanned == bbbench.spec("bbbench/Obstacles-v1").with_height_scan()
    # The first five values are the blind observation, unchanged.
    observation, _ = env.reset(seed=3)
    blind_observation, _ = blind.reset(seed=3)
    np.testing.assert_array_equal(observation[:5], blind_observation)
    # On flat ground the scan reads minus the wheel radius: the axle is 0.1 m up.
    flat, _ = bbbench.make("bbbench/FlatBalance-v0", height_scan=True).reset(seed=0)
    np.testing.assert_allclose(flat[5:], -0.1, atol=2e-3)


@pytest.mark.parametrize("task_id", ["bbbench/Obstacles-v1", "bbbench/Slopes-v1"])
def test_20000_random_steps_with_the_height_scan_stay_in_space(task_id):
    env = bbbench.make(task_id, height_scan=True)
    env.action_space.seed(0)
    observation, _ = env.reset(seed=0)
    for _ in range(20_000):
        assert env.observation_space.contains(observation), observation
        observation, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            observation, _ = env.reset()


def test_height_scan_keyword_mistakes_are_clear():
    with pytest.raises(ValueError, match="height_scan must be True or False"):
        bbbench.make("bbbench/Slopes-v1", height_scan="yes")
    spec = bbbench.spec("bbbench/MultiBalance-v0")
    with pytest.raises(ValueError, match="single-bot option"):
        dataclasses.replace(spec, height_scan=True)


def test_the_height_scan_hashes_only_when_on():
    """Adding the option moved no published fingerprint: v0 specs hash as before."""
    spec = bbbench.spec("bbbench/FlatBalance-v0")
    assert spec.with_height_scan(False).spec_hash == spec.spec_hash
    assert spec.with_height_scan().spec_hash != spec.spec_hash


def test_eval_plays_a_height_scan_policy_with_the_scan_on(tmp_path):
    """A PPO zip trained with height_scan=True fits every single-bot task of its robot
    (played with the scan on, recorded in the results), and none of the multi-bot ones."""
    from stable_baselines3 import PPO

    from bbbench.evaluation import evaluate, select_tasks
    from bbbench.policies import load_policy

    env = bbbench.make("bbbench/Slopes-v1", height_scan=True)
    PPO("MlpPolicy", env, n_steps=64, batch_size=64, seed=0, device="cpu").learn(64).save(
        tmp_path / "scan.zip"
    )
    policy = load_policy(tmp_path / "scan.zip")
    assert policy.height_scan
    two_wheel = bbbench.list_tasks(multi_agent=False, latest=True)
    two_wheel = [t for t in two_wheel if bbbench.spec(t).robot == "two-wheel"]
    assert select_tasks(policy) == two_wheel
    document = evaluate(policy, ["bbbench/Slopes-v1"], episodes=1, workers=1).document
    (task,) = document["tasks"]
    assert task["height_scan"] is True
    assert task["fingerprint"] == bbbench.spec("bbbench/Slopes-v1").with_height_scan().fingerprint
    blind = evaluate(load_policy("pd"), ["bbbench/Slopes-v1"], episodes=1, workers=1)
    assert "height_scan" not in blind.document["tasks"][0]
    with pytest.raises(Exception, match=r"Box\(17,\)"):
        select_tasks(policy, ["bbbench/MultiBalance-v0"])

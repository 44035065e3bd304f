"""Several bots in one world: the PettingZoo parallel tasks and their SB3 adapter."""

from __future__ import annotations

import hashlib
import math
import subprocess
import sys
import warnings

import cloudpickle
import gymnasium as gym
import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

import bbbench
from bbbench.envs.multi import MultiBalanceEnv
from bbbench.robots.layout import INDEX
from bbbench.tasks.group import MAX_BOTS, NEIGHBOUR_FIELDS, Group, spawn_poses
from bbbench.tasks.observation import neighbour_layout

MULTI = "bbbench/MultiBalance-v0"
BUMPS = "bbbench/MultiBumps-v0"
# The crossing tasks (bots each on their own); the team tasks: tests/test_column.py.
MULTI_TASKS = [
    task_id
    for task_id in bbbench.list_tasks(multi_agent=True)
    if bbbench.spec(task_id).scenario == "crossing"
]


def fixed_actions(env, step: int) -> dict:
    """A fixed, varied discrete action per live agent: the same for any process."""
    return {agent: (step * 7 + 3 * env.agent_index[agent]) % 9 for agent in env.agents}


def play(env, seed: int, steps: int, digest=None):
    """Play episode `seed` with `fixed_actions` for up to `steps` steps; hash what it gives."""
    digest = hashlib.sha256() if digest is None else digest
    observations, _ = env.reset(seed=seed)
    for agent in sorted(observations):
        digest.update(observations[agent].tobytes())
    for t in range(steps):
        if not env.agents:
            break
        observations, rewards, terminations, _, _ = env.step(fixed_actions(env, t))
        for agent in sorted(observations):
            digest.update(observations[agent].tobytes())
            digest.update(np.float64(rewards[agent]).tobytes())
            digest.update(bytes([terminations[agent]]))
    return digest


def episodes_digest(task_id: str, seeds, steps: int = 60, **kwargs) -> str:
    env = bbbench.make_parallel(task_id, **kwargs)
    digest = hashlib.sha256()
    for seed in seeds:
        play(env, seed, steps, digest)
    env.close()
    return digest.hexdigest()


def test_the_multi_bot_tasks_are_in_the_suite_and_made_by_make_parallel():
    assert MULTI_TASKS == [
        MULTI,
        "bbbench/MultiBalance-v1",
        BUMPS,
        "bbbench/MultiBumps-v1",
        "bbbench/MultiNoisySensors-v0",
    ]
    for task_id in MULTI_TASKS:
        spec = bbbench.spec(task_id)
        assert spec.multi_agent
        assert spec.group.n_bots == 4
        assert len(spec.eval_seeds) == 100
        env = bbbench.make_parallel(task_id)
        assert isinstance(env, MultiBalanceEnv)
        assert env.possible_agents == [f"bot_{i}" for i in range(4)]
    assert bbbench.spec(BUMPS).difficulty == 0.3


def test_n_bots_changes_the_fingerprint():
    spec = bbbench.spec(MULTI)
    assert spec.with_n_bots(8).fingerprint != spec.fingerprint
    assert spec.with_n_bots(8).spec_hash != spec.spec_hash


@pytest.mark.parametrize("task_id", MULTI_TASKS)
@pytest.mark.parametrize("action_mode", ["discrete", "continuous"])
def test_pettingzoo_parallel_api_test(task_id, action_mode):
    env = bbbench.make_parallel(task_id, n_bots=3, action_mode=action_mode)
    parallel_api_test(env, num_cycles=200)


def test_spaces_are_cached_and_shared_by_every_agent():
    env = bbbench.make_parallel(MULTI, n_bots=5)
    first = env.possible_agents[0]
    for agent in env.possible_agents:
        assert env.observation_space(agent) is env.observation_space(first)
        assert env.action_space(agent) is env.action_space(first)
    assert env.action_space(first) == gym.spaces.Discrete(9)
    continuous = bbbench.make_parallel(MULTI, action_mode="continuous")
    flat = bbbench.make("bbbench/FlatBalance-v0", action_mode="continuous")
    assert continuous.action_space("bot_0") == flat.action_space
    single = bbbench.make("bbbench/FlatBalance-v0").observation_space
    space = env.observation_space(first)
    assert space.shape == (5 + 4 * Group().neighbours,)
    np.testing.assert_array_equal(space.low[:5], single.low)
    np.testing.assert_array_equal(space.high[:5], single.high)


def test_the_single_bot_layout_comes_first_unchanged():
    """The first five values are what BalanceEnv would observe of the same bot."""
    env = bbbench.make_parallel(MULTI, n_bots=2)
    observations, _ = env.reset(seed=11)
    for agent, observation in observations.items():
        bot = env.scene.bots[env.agent_index[agent]]
        state = bot.read()
        assert observation[INDEX["pitch"]] == np.float32(state.pitch)
        assert observation[INDEX["wheel_command"]] == 0.0
        assert 0.2 <= observation[INDEX["target_velocity"]] <= 0.8


@pytest.mark.parametrize("task_id", bbbench.list_tasks(multi_agent=True))
def test_observations_stay_in_their_space_at_every_step(task_id):
    n_bots = 6 if task_id in MULTI_TASKS else 4  # a team (tests/test_column.py) takes 2-4
    env = bbbench.make_parallel(task_id, n_bots=n_bots, action_mode="continuous")
    rng = np.random.default_rng(0)
    for seed in (1, 2):
        observations, _ = env.reset(seed=seed)
        while env.agents:
            for agent, observation in observations.items():
                assert env.observation_space(agent).contains(observation), (agent, observation)
            # Each agent's width: 2 for the steering robot, 6 for a wheel-legged one.
            widths = {a: env.action_space(a).shape[0] for a in env.agents}
            actions = {a: rng.uniform(-1, 1, size=widths[a]).astype(np.float32) for a in env.agents}
            observations, *_ = env.step(actions)
        for agent, observation in observations.items():
            assert env.observation_space(agent).contains(observation)


def test_neighbour_block_sees_the_others_in_the_bots_own_frame():
    env = bbbench.make_parallel(MULTI, n_bots=2)
    observations, _ = env.reset(seed=5)
    k = Group().neighbours
    (x0, y0), (x1, y1) = (env.scene.bots[i].read().position[:2] for i in range(2))
    for agent, other in (("bot_0", (x1 - x0, y1 - y0)), ("bot_1", (x0 - x1, y0 - y1))):
        heading = env.scene.bots[env.agent_index[agent]].read().heading
        right, forward = observations[agent][5:7]
        assert forward == pytest.approx(other[0] * heading[0] + other[1] * heading[1], abs=1e-5)
        assert right == pytest.approx(other[0] * heading[1] - other[1] * heading[0], abs=1e-5)
        # Two bots facing the centre from around a circle: the other is ahead.
        assert forward > 0
        # One neighbour of K: the other slots are zeros.
        assert not observations[agent][5 + len(NEIGHBOUR_FIELDS) :].any()
    assert k > 1


def test_spawns_face_the_centre_so_paths_cross():
    group = Group(n_bots=8)
    poses = spawn_poses(np.random.default_rng(3), group)
    for (x, y), yaw in poses:
        assert math.hypot(x, y) == pytest.approx(group.spawn_radius)
        forward = (-math.sin(yaw), math.cos(yaw))
        to_centre = (-x / group.spawn_radius, -y / group.spawn_radius)
        cosine = forward[0] * to_centre[0] + forward[1] * to_centre[1]
        assert cosine >= math.cos(group.heading_jitter) - 1e-9
    gaps = [math.dist(a[0], b[0]) for i, a in enumerate(poses) for b in poses[i + 1 :]]
    assert min(gaps) > 0.6


def test_bots_meet_in_the_middle():
    """Driven forward with PD, the bots come within a bot's width of another."""
    from bbbench.policies import PDController

    pd = PDController()
    env = bbbench.make_parallel(MULTI, n_bots=4)
    observations, _ = env.reset(seed=bbbench.spec(MULTI).eval_seeds[0])
    closest = np.inf
    for _ in range(800):
        if not env.agents:
            break
        observations, *_ = env.step({a: pd(observations[a][:5]) for a in env.agents})
        positions = [bot.read().position[:2] for bot in env.scene.bots]
        closest = min(
            closest,
            min(math.dist(p, q) for i, p in enumerate(positions) for q in positions[i + 1 :]),
        )
    assert closest < 0.5


@pytest.mark.parametrize("task_id", MULTI_TASKS)
def test_same_seed_same_episode_different_seed_different_episode(task_id):
    seeds = [bbbench.spec(task_id).eval_seeds[0], 7, 8]
    assert episodes_digest(task_id, seeds) == episodes_digest(task_id, seeds)
    assert episodes_digest(task_id, [7]) != episodes_digest(task_id, [8])


def test_determinism_across_processes_over_several_episodes():
    seeds = [3, 4, 2**31]
    script = (
        "import sys; sys.path.insert(0, 'tests'); from test_multi import episodes_digest\n"
        f"for task in {MULTI_TASKS!r}:\n"
        f"    print('digest', episodes_digest(task, {seeds!r}, n_bots=5))\n"
    )
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    there = [line.split()[1] for line in run.stdout.splitlines() if line.startswith("digest ")]
    assert there == [episodes_digest(task, seeds, n_bots=5) for task in MULTI_TASKS]


def test_an_episode_does_not_depend_on_the_episodes_before_it():
    """Bots that fell and left the world come back exactly as in a fresh world."""
    seed = bbbench.spec(BUMPS).eval_seeds[1]
    fresh = episodes_digest(BUMPS, [seed], steps=150, n_bots=6)
    env = bbbench.make_parallel(BUMPS, n_bots=6)
    for other in (5, 6):
        play(env, other, 150)
    assert len(env.ended_at) > 0  # some bots fell, and were set aside
    assert play(env, seed, 150).hexdigest() == fresh


def test_a_fallen_bot_leaves_the_world():
    env = bbbench.make_parallel(MULTI, n_bots=2)
    observations, _ = env.reset(seed=3)
    assert observations["bot_1"][5:7].any()  # each sees the other
    while len(env.agents) == 2:
        observations, _, terminations, _, _ = env.step({"bot_0": 0, "bot_1": 4})
    assert env.agents == ["bot_1"]
    assert terminations["bot_0"]
    observations, *_ = env.step({"bot_1": 4})
    assert not observations["bot_1"][5:].any()  # nobody left to see
    x, _, _ = env.scene.bots[0].read().position
    assert x > 100


def test_the_inlined_observation_and_reward_agree_with_the_shared_definitions():
    from bbbench.robots.layout import observe, sensed

    rng = np.random.default_rng(0)
    for pitch, rate, wheel in rng.uniform(-80, 80, size=(200, 3)):
        expected = observe(pitch, rate, wheel, 1.5, 0.5)
        np.testing.assert_array_equal(
            np.array([*sensed(pitch, rate, wheel), 1.5, 0.5], dtype=np.float32), expected
        )
    env = bbbench.make_parallel(MULTI, n_bots=3)
    env.reset(seed=8)
    for t in range(40):
        live = list(zip(env.agents, env.scene.live, strict=True))
        _, rewards, _, _, infos = env.step(fixed_actions(env, t))
        for agent, i in live:
            state = env.scene.bots[i].read() if agent in env.agents else None
            if state is None:
                continue
            error = abs(state.forward_velocity - env.scene.episode.targets[i, t + 1])
            terms = env.task.reward.terms(state.pitch, error)
            assert (infos[agent]["reward_upright"], infos[agent]["reward_velocity"]) == terms
            assert rewards[agent] == sum(terms)


def test_reset_without_a_seed_continues_the_seeded_sequence():
    env = bbbench.make_parallel(MULTI)
    _, first = env.reset(seed=42)
    _, second = env.reset()
    _, again = env.reset(seed=42)
    _, second_again = env.reset()
    assert first["bot_0"]["episode_seed"] == again["bot_0"]["episode_seed"] == 42
    assert second["bot_0"]["episode_seed"] == second_again["bot_0"]["episode_seed"] != 42


def test_seed_decides_terrain_spawns_and_targets():
    env = bbbench.make_parallel(BUMPS)
    env.reset(seed=1)
    heights, targets = env.scene.ground.heightmap.heights.copy(), env.scene.episode.targets.copy()
    positions = [bot.read().position for bot in env.scene.bots]
    env.reset(seed=2)
    assert not np.array_equal(heights, env.scene.ground.heightmap.heights)
    assert not np.array_equal(targets, env.scene.episode.targets)
    env.reset(seed=1)
    np.testing.assert_array_equal(heights, env.scene.ground.heightmap.heights)
    np.testing.assert_array_equal(targets, env.scene.episode.targets)
    assert positions == [bot.read().position for bot in env.scene.bots]
    # Each bot has its own targets.
    assert len({tuple(row) for row in targets}) == len(targets)


def test_bots_start_level_on_terrain():
    env = bbbench.make_parallel(BUMPS, n_bots=16, difficulty=1.0)
    for seed in (1, 2, 3):
        observations, _ = env.reset(seed=seed)
        for _ in range(5):
            observations, _, terminations, _, _ = env.step({a: 4 for a in env.agents})
        assert not any(terminations.values())
        for agent, observation in observations.items():
            assert abs(observation[INDEX["pitch"]]) < 0.2, agent


def test_cloudpickled_copies_are_independent():
    env = bbbench.make_parallel(MULTI, n_bots=3)
    env.reset(seed=9)
    for t in range(10):
        env.step(fixed_actions(env, t))
    copy = cloudpickle.loads(cloudpickle.dumps(env))
    assert copy.agents == []  # a copy has no world until its reset
    copy_first, _ = copy.reset(seed=9)
    fresh = bbbench.make_parallel(MULTI, n_bots=3)
    fresh_first, _ = fresh.reset(seed=9)
    for agent in fresh_first:
        np.testing.assert_array_equal(copy_first[agent], fresh_first[agent])
    # Stepping the copy leaves the original where it was, and the other way round.
    before = [bot.read() for bot in env.scene.bots]
    for t in range(20):
        copy.step(fixed_actions(copy, t))
        fresh.step(fixed_actions(fresh, t))
    assert before == [bot.read() for bot in env.scene.bots]
    assert [bot.read() for bot in copy.scene.bots] == [bot.read() for bot in fresh.scene.bots]


def test_fallen_agents_are_terminated_removed_and_never_revived():
    env = bbbench.make_parallel(MULTI, n_bots=4)
    env.reset(seed=3)
    ended: set[str] = set()
    steps = 0
    while env.agents:
        live = set(env.agents)
        assert not live & ended  # never revived
        observations, rewards, terminations, truncations, infos = env.step(
            {a: 4 for a in env.agents}  # no wheel-speed change: every bot falls
        )
        steps += 1
        assert set(observations) == set(rewards) == set(terminations) == live
        assert set(truncations) == set(infos) == live
        for agent in live:
            assert (
                infos[agent]["reward_upright"] + infos[agent]["reward_velocity"] == (rewards[agent])
            )
            if terminations[agent]:
                ended.add(agent)
                assert agent not in env.agents
            else:
                assert agent in env.agents
    assert ended == set(env.possible_agents)
    assert steps < 300
    # Nobody left: step({}) is harmless, as often as it is called.
    for _ in range(3):
        assert env.step({}) == ({}, {}, {}, {}, {})


def test_time_limit_truncates_every_agent_left():
    from bbbench.policies import PDController

    pd = PDController()
    env = bbbench.make_parallel(MULTI, n_bots=3, max_episode_steps=30)
    observations, _ = env.reset(seed=1)
    for _ in range(30):
        live = list(env.agents)
        observations, _, terminations, truncations, _ = env.step(
            {a: pd(observations[a][:5]) for a in env.agents}
        )
    assert not any(terminations.values())
    assert set(truncations) == set(live)
    assert all(truncations.values())
    assert env.agents == []


@pytest.mark.parametrize("n_bots", [2, MAX_BOTS])
def test_n_bots_at_the_ends_of_its_range(n_bots):
    env = bbbench.make_parallel(BUMPS, n_bots=n_bots)
    observations, _ = env.reset(seed=4)
    assert len(observations) == len(env.agents) == n_bots
    for t in range(50):
        observations, *_ = env.step(fixed_actions(env, t))
        for agent, observation in observations.items():
            assert env.observation_space(agent).contains(observation)
    k = Group().neighbours
    seen = min(k, n_bots - 1) * len(NEIGHBOUR_FIELDS)
    first = observations[next(iter(observations))]
    assert first[5 : 5 + seen].any()
    assert not first[5 + seen :].any()


def test_rgb_array_shows_the_whole_group():
    env = bbbench.make_parallel(MULTI, n_bots=8, render_mode="rgb_array")
    env.reset(seed=1)
    frame = env.render()
    assert frame.shape == (360, 480, 3)
    assert frame.dtype == np.uint8
    assert frame.std() > 10  # not a blank frame
    # The camera frames the group: every bot's torso projects inside the frame.
    for t in range(400):
        if t % 100 == 0:
            assert_every_bot_in_view(env)
        env.step(fixed_actions(env, t))
    assert not np.array_equal(frame, env.render())


def assert_every_bot_in_view(env) -> None:
    from bbbench.envs.multi import CAMERA_PITCH, CAMERA_YAW, RENDER_HEIGHT, RENDER_WIDTH

    target, distance = env.camera()
    client = env.scene.world.client
    view = np.array(
        client.computeViewMatrixFromYawPitchRoll(target, distance, CAMERA_YAW, CAMERA_PITCH, 0, 2)
    ).reshape(4, 4, order="F")
    projection = np.array(
        client.computeProjectionMatrixFOV(50.0, RENDER_WIDTH / RENDER_HEIGHT, 0.05, 100.0)
    ).reshape(4, 4, order="F")
    for bot in env.scene.live_bots:  # a fallen bot has left the world
        for height in (0.0, 0.5):  # the wheels' contact and the torso's top
            x, y, _ = bot.read().position
            clip = projection @ view @ np.array([x, y, height, 1.0])
            ndc = clip[:2] / clip[3]
            assert np.all(np.abs(ndc) < 0.95), (bot.body, ndc)


@pytest.mark.parametrize("n_bots", [1, 17, 0, 2.5, "4", True])
def test_n_bots_out_of_range_is_refused(n_bots):
    with pytest.raises(ValueError, match=r"n_bots must be a whole number from 2 to 16"):
        bbbench.make_parallel(MULTI, n_bots=n_bots)


def test_bad_actions_name_the_agent_and_what_was_expected():
    env = bbbench.make_parallel(MULTI, n_bots=3)
    env.reset(seed=3)
    with pytest.raises(
        ValueError, match=r"unknown agent\(s\) 'bot_7'.*agents bot_0, bot_1, bot_2$"
    ):
        env.step({"bot_0": 4, "bot_1": 4, "bot_2": 4, "bot_7": 4})
    with pytest.raises(
        ValueError, match=r"no action for live agent\(s\) 'bot_1'.*got actions for bot_0, bot_2$"
    ):
        env.step({"bot_0": 4, "bot_2": 4})
    with pytest.raises(ValueError, match=r"action for 'bot_2': discrete action 11"):
        env.step({"bot_0": 4, "bot_1": 4, "bot_2": 11})
    with pytest.raises(ValueError, match=r"unknown agent 'robot'"):
        env.observation_space("robot")


def test_actions_for_agents_whose_episode_ended_are_ignored():
    """TorchRL sends an action for every possible agent: those of ended agents are ignored,
    and the step plays as if they had not been sent."""
    every = bbbench.make_parallel(MULTI, n_bots=3)
    live_only = bbbench.make_parallel(MULTI, n_bots=3)
    for env in (every, live_only):
        env.reset(seed=3)
        while "bot_0" in env.agents:
            env.step({a: 0 for a in env.agents})
    assert every.agents == live_only.agents
    assert every.agents  # some are still up
    for _ in range(5):
        got = every.step(dict.fromkeys(every.possible_agents, 4))
        expected = live_only.step(dict.fromkeys(live_only.agents, 4))
        assert "bot_0" not in got[0]
        assert list(got[0]) == list(expected[0])
        for agent in got[0]:
            np.testing.assert_array_equal(got[0][agent], expected[0][agent])
        assert got[1:] == expected[1:]
    fresh = bbbench.make_parallel(MULTI, n_bots=3)
    with pytest.raises(ValueError, match=r"before reset\(\): call reset\(\) first"):
        fresh.step({"bot_0": 4})
    assert fresh.step({}) == ({}, {}, {}, {}, {})


def test_every_agent_has_the_same_info_keys_at_reset_and_at_every_step():
    env = bbbench.make_parallel(MULTI, n_bots=4)
    _, infos = env.reset(seed=2)
    keys = {tuple(info) for info in infos.values()}
    assert keys == {("reward_upright", "reward_velocity", "velocity_error", "episode_seed")}
    assert {info["episode_seed"] for info in infos.values()} == {2}
    while env.agents:
        _, _, _, _, infos = env.step({a: 0 for a in env.agents})
        assert {tuple(info) for info in infos.values()} <= keys


def test_reset_options_are_ignored_with_one_warning_that_says_where_n_bots_goes():
    env = bbbench.make_parallel(MULTI)
    with pytest.warns(UserWarning, match=r"ignored 'n_bots'.*make_parallel\(.*n_bots=8\)"):
        observations, _ = env.reset(seed=0, options={"n_bots": 8})
    assert len(observations) == 4
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env.reset(seed=0, options={"n_bots": 8})  # once per env


def test_wrong_constructors_say_which_to_use():
    with pytest.raises(ValueError, match=r"multi-bot \(PettingZoo\) task.*make_parallel"):
        bbbench.make(MULTI)
    with pytest.raises(ValueError, match=r"single-bot task.*bbbench.make"):
        bbbench.make_parallel("bbbench/FlatBalance-v0")
    with pytest.raises(TypeError, match=r"unknown keyword argument\(s\) \['difficulty'\]"):
        bbbench.make_parallel(MULTI, difficulty=0.5)
    with pytest.raises(TypeError, match=r"\['bots'\].*n_bots"):
        bbbench.make_parallel(MULTI, bots=3)


def test_the_task_pages_table_matches_the_neighbour_block():
    from test_column import page_observation_rows

    rows = page_observation_rows(MULTI)
    block = neighbour_layout(Group())  # every neighbour's slot, the nearest first
    assert len(rows) == 5 + len(block)
    for k, field in enumerate(block):
        name, low, high, unit, _ = rows[5 + k]
        assert (name, unit) == (field.name, field.unit)
        assert field.name.endswith(NEIGHBOUR_FIELDS[k % len(NEIGHBOUR_FIELDS)])
        assert (float(low), float(high)) == (field.low, field.high)
    assert "MultiBalance: v0: initial release." in MultiBalanceEnv.__doc__


# -- stable-baselines3 ------------------------------------------------------------------


def test_make_vec_slots_follow_the_bots_and_truncation_reaches_sb3():
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback

    vec = bbbench.make_vec(MULTI, n_envs=2, n_bots=3, max_episode_steps=25)
    assert vec.num_envs == 6
    ends = {"fell": 0, "time limit": 0, "idle": 0, "episode stats": 0}

    class Spy(BaseCallback):
        """Reads what SB3's own rollout loop received."""

        def _on_step(self) -> bool:
            for info, done in zip(self.locals["infos"], self.locals["dones"], strict=True):
                if done:
                    assert info["terminal_observation"].shape == vec.observation_space.shape
                    kind = (
                        "idle"
                        if info.get("idle")
                        else "time limit"
                        if info["TimeLimit.truncated"]
                        else "fell"
                    )
                    ends[kind] += 1
                    ends["episode stats"] += "episode" in info
            return True

    model = PPO("MlpPolicy", vec, n_steps=50, batch_size=100, n_epochs=2, seed=0)
    model.learn(300, callback=Spy())
    assert ends["time limit"] > 0
    assert ends["episode stats"] == ends["fell"] + ends["time limit"]
    assert model.ep_info_buffer
    assert all(e["l"] <= 25 for e in model.ep_info_buffer)


def test_a_short_ppo_run_learns_end_to_end_on_multibumps():
    from stable_baselines3 import PPO

    vec = bbbench.make_vec(BUMPS, n_envs=1, n_bots=2, action_mode="continuous")
    model = PPO("MlpPolicy", vec, n_steps=64, batch_size=64, n_epochs=1, seed=1)
    model.learn(256)
    actions, _ = model.predict(vec.reset(), deterministic=True)
    assert actions.shape == (2, 1)


def test_fallen_slots_report_done_on_the_step_they_fall():
    vec = bbbench.make_vec(MULTI, n_envs=1, n_bots=4)
    vec.seed(3)
    vec.reset()
    env = vec.envs[0]
    done_at: dict[int, int] = {}
    for t in range(400):
        live_before = list(env.agents)
        _, rewards, dones, infos = vec.step(np.full(4, 4))
        for slot in np.flatnonzero(dones):
            if infos[slot].get("idle"):
                continue
            done_at.setdefault(slot, t)
            # Done on the very step the bot fell (not one late, as black_death_v3).
            assert env.possible_agents[slot] in live_before
            assert not infos[slot]["TimeLimit.truncated"]
        if len(done_at) == 4:
            break
        for slot in range(4):
            if slot in done_at and t > done_at[slot]:
                assert rewards[slot] == 0.0  # an idle slot earns nothing
    assert len(done_at) == 4


def test_seeded_vec_envs_repeat_exactly():
    def run() -> bytes:
        vec = bbbench.make_vec(MULTI, n_envs=2, n_bots=2)
        vec.seed(123)
        observations = [vec.reset()]
        for t in range(120):
            observations.append(vec.step(np.full(4, t % 9))[0])
        return np.concatenate(observations).tobytes()

    assert run() == run()


def test_make_vec_of_a_single_bot_task_is_sb3s_own():
    from stable_baselines3.common.vec_env import DummyVecEnv

    vec = bbbench.make_vec("bbbench/FlatBalance-v0", n_envs=2)
    assert isinstance(vec, DummyVecEnv)
    assert vec.num_envs == 2
    with pytest.raises(ValueError, match="n_envs must be a whole number >= 1"):
        bbbench.make_vec(MULTI, n_envs=0)

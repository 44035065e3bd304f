"""Many worlds as one batched env: `bbbench.make_batched` (arrays) and its TorchRL face
`bbbench.marl.batched_env` (what BenchMARL collects from)."""

from __future__ import annotations

import numpy as np
import pytest

import bbbench


def play_parallel(task_id: str, seed: int, actions: np.ndarray, **kwargs):
    """`make_parallel`'s episode from `seed` under `actions` (steps, bots): per step the
    observations (bots, width, zeros for a bot out of it), rewards, ends and live bots,
    until the episode ends."""
    env = bbbench.make_parallel(task_id, **kwargs)
    observations, _ = env.reset(seed=seed)
    agents = env.possible_agents
    rows = []
    for chosen in actions:
        acting = list(env.agents)
        observations, rewards, terminations, truncations, _ = env.step(
            {agent: chosen[agents.index(agent)] for agent in acting}
        )
        width = env.observation_space(agents[0]).shape[0]
        rows.append(
            (
                np.stack([observations.get(a, np.zeros(width, np.float32)) for a in agents]),
                np.array([rewards.get(a, 0.0) for a in agents]),
                np.array([terminations.get(a, False) for a in agents]),
                np.array([truncations.get(a, False) for a in agents]),
                np.array([a in env.agents for a in agents]),
            )
        )
        if not env.agents:
            break
    env.close()
    return rows


@pytest.mark.parametrize(
    ("task_id", "kwargs"),
    [
        ("bbbench/MultiBalance-v1", {}),  # bots fall one by one, the others play on
        ("bbbench/MultiNoisySensors-v0", {}),  # each bot's own sensor errors, per episode
        ("bbbench/Convoy-v0", {"n_bots": 2}),  # a team: one fall ends every bot
        ("bbbench/MultiBumps-v1", {"action_mode": "continuous"}),
        ("bbbench/Swap-v0", {}),  # the steering robot: 27 actions, its own observation
        ("bbbench/ConvoyTurns-v0", {"action_mode": "continuous"}),  # and 2 continuous ones
    ],
)
def test_world_k_plays_make_parallels_episode_from_seed_s_plus_k_bit_for_bit(task_id, kwargs):
    worlds, seed, steps = 3, 40, 400
    env = bbbench.make_batched(task_id, worlds=worlds, **kwargs)
    bots = env.n_bots
    rng = np.random.default_rng(1)
    space = env.single_action_space
    if kwargs.get("action_mode") == "continuous":
        width = space.shape[0]
        actions = rng.uniform(-1, 1, (steps, worlds, bots, width)).astype(np.float32)
    else:
        actions = rng.integers(0, space.n, (steps, worlds, bots))
    first, infos = env.reset(seed=seed)
    assert first.shape == (worlds, bots, env.single_observation_space.shape[0])
    assert infos["live"].all()
    assert list(infos["episode_seed"]) == [40, 41, 42]
    played = [env.step(actions[t]) for t in range(steps)]
    env.close()
    ended = 0
    for k in range(worlds):
        expected = play_parallel(task_id, seed + k, actions[:, k], **kwargs)
        assert len(expected) < steps  # the episode ended (random play), and then ...
        for t, (observation, reward, terminated, truncated, live) in enumerate(expected):
            got_observation, got_reward, got_terminated, got_truncated, got_infos = played[t]
            assert got_observation.dtype == np.float32
            assert np.array_equal(got_observation[k], observation), (k, t)
            assert np.array_equal(got_reward[k], reward), (k, t)
            assert np.array_equal(got_terminated[k], terminated), (k, t)
            assert np.array_equal(got_truncated[k], truncated), (k, t)
            assert np.array_equal(got_infos["live"][k], live), (k, t)
        # ... the world restarted on its own at the next step, on its own next seed.
        restart = played[len(expected)]
        assert restart[4]["live"][k].all()
        assert not restart[1][k].any()
        assert not (restart[2][k].any())
        assert not (restart[3][k].any())
        assert restart[4]["episode_seed"][k] != seed + k
        ended += 1
    assert ended == worlds


def test_a_mixed_teams_worlds_play_make_parallels_episodes_in_a_group_per_robot():
    """Each robot keeps its own spaces: observations and actions are dicts by group, each
    group's bots in order, and world k is `make_parallel`'s episode from seed S + k, in
    one process and in two."""
    task_id, worlds, seed, steps = "bbbench/MixedBeamCarry-v0", 2, 5, 120
    parallel = bbbench.make_parallel(task_id)
    groups = parallel.task.robot_groups
    rng = np.random.default_rng(2)
    actions = [
        {
            g: rng.uniform(
                -1, 1, (worlds, len(bots), parallel.action_space(f"bot_{bots[0]}").shape[0])
            ).astype(np.float32)
            for g, bots in groups.items()
        }
        for _ in range(steps)
    ]
    played = {}
    for workers in (1, 2):
        env = bbbench.make_batched(task_id, worlds=worlds, workers=workers)
        assert set(env.single_observation_space) == set(groups)
        assert env.action_space["two-wheel"].shape == (worlds, 1, 1)
        assert env.observation_space["wheel-legged"].shape == (worlds, 2, 31)
        first, _ = env.reset(seed=seed)
        played[workers] = [first, *(env.step(chosen) for chosen in actions)]
        env.close()
    for one, two in zip(played[1][1:], played[2][1:], strict=True):
        for a, b in zip(one[:4], two[:4], strict=True):
            if isinstance(a, dict):
                assert all(a[g].tobytes() == b[g].tobytes() for g in groups)
            else:
                assert a.tobytes() == b.tobytes()
    for k in range(worlds):
        observations, _ = parallel.reset(seed=seed + k)
        for g, bots in groups.items():
            assert np.array_equal(
                played[1][0][g][k], np.stack([observations[f"bot_{i}"] for i in bots])
            )
        for t, chosen in enumerate(actions):
            if not parallel.agents:
                break
            by_bot = {
                f"bot_{i}": chosen[g][k, r]
                for g, bots in groups.items()
                for r, i in enumerate(bots)
            }
            observations, rewards, *_ = parallel.step({a: by_bot[a] for a in parallel.agents})
            got_observations, got_rewards = played[1][t + 1][:2]
            for g, bots in groups.items():
                for r, i in enumerate(bots):
                    want = observations.get(f"bot_{i}")
                    want = np.zeros_like(got_observations[g][k, r]) if want is None else want
                    assert np.array_equal(got_observations[g][k, r], want), (k, t, i)
            assert np.array_equal(got_rewards[k], [rewards.get(f"bot_{i}", 0.0) for i in range(3)])
    parallel.close()


def test_a_mixed_teams_actions_must_be_a_dict_of_each_groups_array():
    env = bbbench.make_batched("bbbench/MixedBeamCarry-v0", worlds=2)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"dict of actions by group.*two-wheel") as caught:
        env.step(np.zeros((2, 3, 6), np.float32))
    assert "\n" not in str(caught.value)
    with pytest.raises(ValueError, match=r"shape \(2, 2, 6\)"):
        env.step({"two-wheel": np.zeros((2, 1, 1)), "wheel-legged": np.zeros((2, 2, 5))})
    env.close()


def test_the_bytes_do_not_depend_on_the_number_of_worker_processes():
    def run(workers: int) -> list[np.ndarray]:
        env = bbbench.make_batched("bbbench/MultiBalance-v1", worlds=5, workers=workers)
        rng = np.random.default_rng(0)
        out = [env.reset(seed=7)[0]]
        for _ in range(300):  # through falls, world ends and restarts
            observations, rewards, terminated, _truncated, infos = env.step(
                rng.integers(0, 9, (5, 4))
            )
            out += [observations, rewards, terminated, infos["live"], infos["episode_seed"]]
        env.close()
        return out

    one, three = run(1), run(3)
    assert all(a.tobytes() == b.tobytes() for a, b in zip(one, three, strict=True))


def test_the_spaces_are_the_worlds_of_the_parallel_envs():
    env = bbbench.make_batched("bbbench/BeamCarry-v0", worlds=4)
    parallel = bbbench.make_parallel("bbbench/BeamCarry-v0")
    assert env.single_observation_space == parallel.observation_space("bot_0")
    assert env.observation_space.shape == (4, 3, 19)
    assert env.action_space.shape == (4, 3)
    assert env.metadata["autoreset_mode"].value == "NextStep"
    env.close()


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: bbbench.make_batched("bbbench/FlatBalance-v1", worlds=2), "single-bot task"),
        (lambda: bbbench.make_batched("bbbench/MultiBalance-v1", worlds=0), "worlds=0"),
        (lambda: bbbench.make_batched("bbbench/MultiBalance-v1", worlds=2.5), "whole number"),
        (lambda: bbbench.make_batched("bbbench/MultiBalance-v1", worlds=True), "whole number"),
        (lambda: bbbench.make_batched("bbbench/MultiBalance-v1", worlds=10**6), "GiB"),
        (lambda: bbbench.make_batched("bbbench/MultiBalance-v1", worlds=2, workers=3), "workers"),
    ],
)
def test_bad_batches_are_refused_with_one_line(call, message):
    with pytest.raises(ValueError, match=message) as caught:
        call()
    assert "\n" not in str(caught.value)


def test_actions_of_the_wrong_shape_are_refused():
    env = bbbench.make_batched("bbbench/MultiBalance-v1", worlds=2)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(2, 4\)"):
        env.step(np.zeros((4,), dtype=int))
    env.close()


# -- the TorchRL face -------------------------------------------------------------------


@pytest.mark.parametrize(
    ("task_id", "mode"),
    [
        ("bbbench/MultiBalance-v1", "discrete"),
        ("bbbench/BeamCarry-v0", "discrete"),  # the team's episode ends at once
        ("bbbench/MultiBumps-v1", "continuous"),
        ("bbbench/Swap-v0", "discrete"),
        ("bbbench/ConvoyTurns-v0", "continuous"),
        ("bbbench/MixedBeamCarry-v0", "continuous"),  # a group per robot, own spaces
    ],
)
def test_each_world_is_torchrls_own_pettingzoo_wrapper_bit_for_bit(task_id, mode):
    """World k of the batched TorchRL env writes what TorchRL's `PettingZooWrapper` over
    `make_parallel` seeded S + k writes, key for key, over falls, masked bots, episode
    ends and the collector's partial resets."""
    import torch
    from torchrl.envs.libs.pettingzoo import PettingZooWrapper

    from bbbench.marl import batched_env

    worlds, seed = 2, 3
    batched = batched_env(task_id, worlds=worlds, action_mode=mode)
    batched.set_seed(seed)
    options = {"use_mask": True, "done_on_any": False, "categorical_actions": True}
    singles = [  # a mixed team's wrapper groups its agents by robot, as the batch does
        PettingZooWrapper(
            bbbench.make_parallel(task_id, action_mode=mode),
            group_map=batched.group_map,
            **options,
        )
        for k in range(worlds)
    ]
    state = batched.reset()
    states = [env.reset(seed=seed + k) for k, env in enumerate(singles)]
    generator = torch.Generator().manual_seed(0)
    ended = fell = 0
    for _ in range(500):
        for group in batched.group_map:
            spec = batched.full_action_spec[group, "action"]
            if mode == "discrete":
                action = torch.randint(spec.space.n, spec.shape, generator=generator)
            else:
                action = torch.rand(spec.shape, generator=generator) * 2 - 1
            state.set((group, "action"), action)
        step, next_state = batched.step_and_maybe_reset(state)
        for k, env in enumerate(singles):
            for group in batched.group_map:
                states[k].set((group, "action"), state[group, "action"][k].clone())
            expected = env.step(states[k])["next"]
            got = step["next"][k]
            assert set(expected.keys(True, True)) - set(got.keys(True, True)) <= {
                (group, "info", "episode_seed") for group in batched.group_map
            }
            for key in expected.keys(True, True):
                if "episode_seed" in key:  # an info key the batched face leaves out
                    continue
                assert expected[key].dtype == got[key].dtype, key
                assert torch.equal(expected[key], got[key]), (key, k)
            fell += int(any((~got[group, "mask"]).any() for group in batched.group_map))
            if expected["done"].all():
                ended += 1
                states[k] = env.reset()
                for group in batched.group_map:
                    observed = next_state[group, "observation"][k]
                    assert torch.equal(states[k][group, "observation"], observed)
            else:
                states[k] = expected.exclude(*((g, "reward") for g in batched.group_map))
        state = next_state
    batched.close()
    assert fell > 0
    assert ended >= worlds


@pytest.mark.parametrize("task_id", ["bbbench/Convoy-v0", "bbbench/MixedBeamCarry-v0"])
def test_the_torchrl_face_passes_torchrls_own_spec_check(task_id):
    from torchrl.envs.utils import check_env_specs

    from bbbench.marl import batched_env

    env = batched_env(task_id, worlds=3, workers=2)
    check_env_specs(env)
    env.close()

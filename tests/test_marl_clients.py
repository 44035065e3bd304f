"""The MARL libraries take the multi-bot envs as they are, with no glue: TorchRL's
`PettingZooWrapper` (BenchMARL's way in) and RLlib's `ParallelPettingZooEnv`.

RLlib pins its own gymnasium (ray[rllib] 2.60: gymnasium 1.2.2), so its test runs in a
second virtual environment that .ci/run makes with the `rllib` extra; elsewhere it is
skipped, unless BBBENCH_REQUIRE_RLLIB=1 (as .ci/run sets there) makes a missing RLlib a
failure.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

import bbbench

MULTI = "bbbench/MultiBalance-v1"


def test_torchrl_pettingzoo_wrapper_rolls_out_300_steps_through_falls():
    torch = pytest.importorskip("torch")
    from torchrl.envs.libs.pettingzoo import PettingZooWrapper

    env = bbbench.make_parallel(MULTI, n_bots=4)
    wrapped = PettingZooWrapper(env, use_mask=True, done_on_any=False, categorical_actions=True)
    wrapped.set_seed(0)
    torch.manual_seed(0)
    rollout = wrapped.rollout(300, break_when_any_done=False)  # random actions: bots fall
    assert rollout.batch_size == torch.Size([300])
    mask = rollout["next", "bot", "mask"]  # which bots were still in the episode
    assert mask.shape == (300, 4)
    assert not mask.all()  # some bot fell before 300 steps ...
    assert mask[0].all()  # ... none at the first
    fell = rollout["next", "bot", "terminated"].squeeze(-1)
    # A bot that falls is terminated in the step it falls, and masked out from there on
    # (until the team's episode ends and the env resets).
    assert torch.equal(fell & mask, torch.zeros_like(fell))
    assert fell.any(dim=0).sum() >= 2
    assert rollout["next", "done"].any()  # every bot down: reset, and played on
    info = rollout["next", "bot", "info"]
    assert set(info.keys()) == {
        "reward_upright",
        "reward_velocity",
        "velocity_error",
        "episode_seed",
    }
    reward = rollout["next", "bot", "reward"].squeeze(-1)
    terms = info["reward_upright"] + info["reward_velocity"]
    assert torch.allclose(reward[mask], terms[mask])
    assert observations_within(rollout["next", "bot", "observation"][mask], env)


@pytest.mark.parametrize(
    "task_id", ["bbbench/BeamCarry-v0", "bbbench/Convoy-v0", "bbbench/ConvoyTurns-v0"]
)
def test_torchrl_wrapper_on_a_team_task_ends_every_agent_at_once_with_one_reward(task_id):
    torch = pytest.importorskip("torch")
    from torchrl.envs.libs.pettingzoo import PettingZooWrapper

    env = bbbench.make_parallel(task_id)
    wrapped = PettingZooWrapper(env, use_mask=True, done_on_any=False, categorical_actions=True)
    wrapped.set_seed(0)
    torch.manual_seed(0)
    rollout = wrapped.rollout(600, break_when_any_done=False)  # random actions: the team falls
    terminated = rollout["next", "bot", "terminated"].squeeze(-1)  # (600, 3)
    ends = terminated.any(dim=1)
    assert ends.sum() >= 2  # fell, reset, fell again
    assert torch.equal(terminated[ends], torch.ones_like(terminated[ends]))  # all at once
    assert rollout["next", "done"][ends].all()
    mask = rollout["next", "bot", "mask"]
    # No bot is left behind: the team ends together, and the reset brings every bot back.
    assert torch.equal(mask, ~ends[:, None].expand_as(mask))
    reward = rollout["next", "bot", "reward"].squeeze(-1)
    assert torch.equal(reward, reward[:, :1].expand_as(reward))  # the team's, for every bot
    info = rollout["next", "bot", "info"]
    assert torch.allclose(reward[mask], (info["reward_upright"] + info["reward_velocity"])[mask])
    assert observations_within(rollout["next", "bot", "observation"][mask], env)


def observations_within(observations, env) -> bool:
    space = env.observation_space(env.possible_agents[0])
    values = observations.numpy()
    return bool(np.all(values >= space.low) and np.all(values <= space.high))


def _rllib():
    try:
        from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
    except ImportError:
        if os.environ.get("BBBENCH_REQUIRE_RLLIB") == "1":
            raise
        pytest.skip("RLlib is not installed: .ci/run runs this test in its rllib venv")
    return ParallelPettingZooEnv


@pytest.mark.parametrize(
    "task_id", [MULTI, "bbbench/BeamCarry-v0", "bbbench/Swap-v0", "bbbench/ConvoyTurns-v0"]
)
def test_rllib_parallel_pettingzoo_env_resets_steps_and_renders(task_id):
    wrapper = _rllib()
    env = wrapper(bbbench.make_parallel(task_id, n_bots=3, render_mode="rgb_array"))
    observations, infos = env.reset(seed=5)
    assert set(observations) == set(infos) == {"bot_0", "bot_1", "bot_2"}
    assert infos["bot_0"]["episode_seed"] == 5
    frame = env.render()
    assert frame.shape == (360, 480, 3)
    steps = 0
    while True:
        actions = {agent: env.action_space[agent].sample() for agent in observations}
        observations, rewards, terminateds, truncateds, _ = env.step(actions)
        steps += 1
        if terminateds["__all__"] or truncateds["__all__"] or steps == 200:
            break
        assert set(rewards) == set(observations)
        assert all(0.0 <= reward <= 0.1 for reward in rewards.values())
    assert steps > 1


def test_rllibs_onnx_export_is_what_bbbench_export_and_eval_take(tmp_path):
    """scripts/rllib_onnx_fixture.py, which wrote tests/data/rllib_flatbalance.onnx, runs
    here, and its fresh file goes through `bbbench export` to a scored policy."""
    import subprocess
    import sys
    from pathlib import Path

    from bbbench.cli import main

    _rllib()
    script = Path(__file__).resolve().parents[1] / "scripts" / "rllib_onnx_fixture.py"
    raw = tmp_path / "model.onnx"
    subprocess.run([sys.executable, str(script), "--out", str(raw)], check=True, timeout=600)
    out = tmp_path / "policy.onnx"
    contract = ["--observation", "5", "--action-space", "Discrete(9)"]
    assert main(["export", str(raw), "--out", str(out), "--output", "output", *contract]) == 0
    task = ["--task", "bbbench/FlatBalance-v1", "--episodes", "1", "--workers", "1"]
    assert main(["eval", str(out), *task]) == 0


def test_rllib_trains_one_policy_shared_by_every_bot(tmp_path):
    """examples/rllib_shared_ppo.py: RLlib's PPO, one `shared` policy over the bots of
    MultiBalance-v1, one iteration on a local Ray."""
    import importlib.util
    from pathlib import Path

    _rllib()
    import ray

    path = Path(__file__).resolve().parents[1] / "examples" / "rllib_shared_ppo.py"
    loaded = importlib.util.spec_from_file_location("rllib_shared_ppo", path)
    example = importlib.util.module_from_spec(loaded)
    loaded.loader.exec_module(example)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        algo = example.build(MULTI, bots=3, env_runners=0, batch=300).build_algo()
        result = algo.train()
        assert result["num_env_steps_sampled_lifetime"] >= 300
        assert set(result["learners"]) >= {"shared"}
        algo.stop()
    finally:
        ray.shutdown()

"""bbbench's multi-bot and team tasks as a BenchMARL task family: BenchMARL's own
Experiment trains on them with no glue."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from benchmarl.algorithms import IppoConfig
from benchmarl.environments import task_config_registry
from benchmarl.experiment import Experiment, ExperimentConfig
from benchmarl.models import MlpConfig

import bbbench
from bbbench.evaluation import evaluate
from bbbench.marl import BbbenchTask


def tiny_config(tmp_path, frames: int, batch: int, discrete: bool = False) -> ExperimentConfig:
    """BenchMARL's experiment config for a few iterations on the CPU, writing nothing."""
    config = ExperimentConfig.get_from_yaml()
    config.sampling_device = config.train_device = "cpu"
    config.prefer_continuous_actions = not discrete
    config.max_n_frames = frames
    config.on_policy_collected_frames_per_batch = batch
    config.on_policy_n_envs_per_worker = 1
    config.on_policy_n_minibatch_iters = 1
    config.on_policy_minibatch_size = min(batch, 100)
    config.evaluation = False
    config.loggers = []
    config.create_json = False
    config.render = False
    config.checkpoint_interval = 0
    config.save_folder = str(tmp_path)
    return config


def ippo_run(task, config: ExperimentConfig, normalization=None) -> Experiment:
    """BenchMARL's IPPO with its MLPs on a task of the family, seed 0, run to its end
    (its observations through `normalization`, by group, if given)."""
    torch.manual_seed(0)
    task = task.get_from_yaml()
    task.observation_normalization = normalization
    experiment = Experiment(
        task=task,
        algorithm_config=IppoConfig.get_from_yaml(),
        model_config=MlpConfig.get_from_yaml(),
        critic_model_config=MlpConfig.get_from_yaml(),
        seed=0,
        config=config,
    )
    experiment.run()
    return experiment


def test_the_family_is_every_latest_multi_bot_task_made_from_the_suite():
    from bbbench.marl.family import task_config

    latest = [t for t in bbbench.list_tasks(latest=True) if bbbench.spec(t).multi_agent]
    assert sorted(task.get_from_yaml().task_id for task in BbbenchTask) == sorted(latest)
    from hydra.core.config_store import ConfigStore

    from bbbench.marl.run import store_task_configs

    store_task_configs()
    stored = ConfigStore.instance().repo["task"]["bbbench"]
    for task in BbbenchTask:
        assert task_config_registry[f"bbbench/{task.name.lower()}"] is task
        # What BenchMARL's hydra CLI finds is what the suite makes.
        expected = task_config(task.get_from_yaml().task_id)
        assert task.get_from_yaml().config == expected
        assert dict(stored[f"{task.name.lower()}.yaml"].node) == expected


@pytest.mark.slow
def test_a_new_team_task_trains_with_benchmarl_without_touching_marl(tmp_path, monkeypatch):
    """A throwaway team task, a row added to the suite and nothing else: the family, its
    configuration and the recipe (its scenario's) come from the suite."""
    import dataclasses

    from bbbench.tasks import suite
    from bbbench.training import train

    row = dataclasses.replace(
        suite.SUITE["bbbench/Convoy-v0"],
        id="bbbench/ThrowawayTeam-v0",
        group=dataclasses.replace(suite.SUITE["bbbench/Convoy-v0"].group, n_bots=2),
    )
    monkeypatch.setitem(suite.SUITE, row.id, row)
    out = tmp_path / "policy.onnx"
    trained = train([row.id], "ippo", out=out, steps=10, n_envs=2, workers=1, final_episodes=1)
    assert out.exists()
    assert trained.results["tasks"][0]["task"] == row.id
    assert trained.recipe.record()["recipe"] == row.id


@pytest.mark.parametrize("continuous", [False, True])
def test_a_task_builds_one_batched_env_of_its_worlds_with_its_bots_in_one_group(continuous):
    task = BbbenchTask.BEAMCARRY_V0.get_from_yaml()
    env = task.get_env_fun(2, continuous, seed=0, device="cpu")()
    assert env.batch_size == (2,)  # BenchMARL uses it as it is: one policy call a step
    assert task.group_map(env) == {"bot": ["bot_0", "bot_1", "bot_2"]}
    assert env.observation_spec["bot", "observation"].shape == (2, 3, 19)
    assert task.observation_spec(env)["bot", "observation"].shape == (3, 19)  # a world's
    assert set(task.info_spec(env)["bot", "info"].keys()) >= {"reward_upright", "velocity_error"}
    action = task.action_spec(env)["bot", "action"]
    assert action.shape == ((3, 1) if continuous else (3,))
    assert task.max_steps(env) == 1500
    rollout = env.rollout(5)
    assert rollout.shape == (2, 5)
    assert rollout["next", "bot", "mask"].all()  # nobody has fallen yet
    env.close()


def test_a_mixed_teams_task_has_a_group_per_robot_in_its_own_spaces():
    task = BbbenchTask.MIXEDBEAMCARRY_V0.get_from_yaml()
    assert not task.supports_discrete_actions()  # the wheel-legged robot's is continuous
    env = task.get_env_fun(2, True, seed=0, device="cpu")()
    assert env.batch_size == (2,)  # one batched env of both worlds: one policy call a step
    assert task.group_map(env) == {"wheel-legged": ["bot_0", "bot_2"], "two-wheel": ["bot_1"]}
    spec = task.observation_spec(env)
    assert spec["wheel-legged", "observation"].shape == (2, 31)
    assert spec["two-wheel", "observation"].shape == (1, 19)
    actions = task.action_spec(env)
    assert actions["wheel-legged", "action"].shape == (2, 6)
    assert actions["two-wheel", "action"].shape == (1, 1)
    rollout = env.rollout(5)
    assert rollout["next", "wheel-legged", "mask"].all()
    reward = rollout["next", "two-wheel", "reward"]
    assert torch.equal(rollout["next", "wheel-legged", "reward"][:, :, :1], reward)  # the team's
    env.close()


@pytest.mark.slow
def test_benchmarl_trains_a_policy_per_robot_of_a_mixed_team(tmp_path):
    config = tiny_config(tmp_path, frames=400, batch=200)
    config.on_policy_n_envs_per_worker = 2  # two worlds of the batched env
    from tensordict.nn import InteractionType, set_interaction_type

    from bbbench.policies import load_policy
    from bbbench.training.benchmarl.train import observation_statistics, team_file

    # Each robot's bots observe through their own group's normalizer (31 and 19 values).
    normalization = observation_statistics("bbbench/MixedBeamCarry-v0", {}, 0, "continuous")
    assert {group: len(mean) for group, (mean, _) in normalization.items()} == {
        "wheel-legged": 31,
        "two-wheel": 19,
    }
    experiment = ippo_run(BbbenchTask.MIXEDBEAMCARRY_V0, config, normalization)
    assert experiment.total_frames == 400
    assert list(experiment.group_map) == ["wheel-legged", "two-wheel"]
    # Exported: a team file of a model per group, its normalizer inside, scored by
    # bbbench as BenchMARL acts (on the observations its normalizers give the models).
    path = tmp_path / "team.zip"
    path.write_bytes(team_file(experiment, "bbbench/MixedBeamCarry-v0", "IPPO", normalization))
    team = load_policy(path)
    assert team.mismatch("bbbench/MixedBeamCarry-v0") is None
    env = BbbenchTask.MIXEDBEAMCARRY_V0.get_from_yaml().get_env_fun(1, True, 3, "cpu")()
    raw = env.reset()
    env.close()
    batch = raw.clone()  # what the models see: through each group's normalizer
    for group, (mean, std) in normalization.items():
        batch[group, "observation"] = (raw[group, "observation"] - torch.tensor(mean)) / std
    with set_interaction_type(InteractionType.DETERMINISTIC), torch.no_grad():
        acted = experiment.algorithm.get_policy_for_collection()(batch)
    # The one world's bots: bot_0 and bot_2 wheel-legged, bot_1 two-wheel.
    legged, wheels = (
        raw[group, "observation"][0].numpy() for group in ("wheel-legged", "two-wheel")
    )
    ours = team.actor("bbbench/MixedBeamCarry-v0").team(
        [legged[0], wheels[0], legged[1]], [0, 1, 2]
    )
    np.testing.assert_allclose(
        np.stack([ours[0], ours[2]]), acted["wheel-legged", "action"][0].numpy(), atol=1e-5
    )
    np.testing.assert_allclose(ours[1], acted["two-wheel", "action"][0, 0].numpy(), atol=1e-5)
    results = evaluate(team, ["bbbench/MixedBeamCarry-v0"], episodes=1, workers=1)
    assert results.document["tasks"][0]["episodes"][0]["length"] >= 1


@pytest.mark.slow
def test_benchmarls_experiment_trains_ippo_on_a_team_task(tmp_path):
    experiment = ippo_run(BbbenchTask.BEAMCARRY_V0, tiny_config(tmp_path, frames=400, batch=200))
    assert experiment.total_frames == 400
    assert experiment.n_iters_performed == 2


def test_the_neighbour_encoder_trains_in_benchmarl_and_exports_as_it_acts(tmp_path):
    import numpy as np

    from bbbench.marl.models import NeighbourEncoderConfig
    from bbbench.policies import export_onnx, load_policy

    config = tiny_config(tmp_path, frames=200, batch=200, discrete=True)
    torch.manual_seed(0)
    experiment = Experiment(
        task=BbbenchTask.BEAMCARRY_V0.get_from_yaml(),
        algorithm_config=IppoConfig.get_from_yaml(),
        model_config=NeighbourEncoderConfig.for_task("bbbench/BeamCarry-v0"),
        critic_model_config=MlpConfig.get_from_yaml(),
        seed=0,
        config=config,
    )
    experiment.run()
    actor = experiment.group_policies["bot"]
    network = next(m for m in actor.modules() if hasattr(m, "net")).net
    path = export_onnx(network, "bbbench/BeamCarry-v0", tmp_path / "ippo.onnx", algorithm="IPPO")
    policy = load_policy(path)
    observations = torch.randn(64, 19)
    observations[:, 9] = 1.0
    observations[:, 14] = (torch.arange(64) % 2).float()
    with torch.no_grad():
        expected = network(observations).numpy()
    scores = policy.actor("bbbench/BeamCarry-v0").program(observations.numpy())
    assert np.abs(scores - expected).max() < 1e-5


def policy_gradient(experiment, batch) -> torch.Tensor:
    """The actor's gradient of the PPO objective on a processed batch, flattened."""
    loss = experiment.losses["bot"]
    actor = [p for p in loss.actor_network_params.values(True, True)]
    value = loss(batch.reshape(-1))["loss_objective"]
    grads = torch.autograd.grad(value, actor, allow_unused=True)
    return torch.cat([g.flatten() for g in grads if g is not None])


@pytest.mark.parametrize("masked", [True, False])
def test_a_fallen_bots_rows_carry_no_policy_gradient(tmp_path, masked):
    """Rows of bots that have fallen (the mask False) are changed at will: with the
    masked IPPO the actor's gradient does not move; with BenchMARL's own, it does."""
    from bbbench.marl.algorithms import MaskedIppoConfig

    config = tiny_config(tmp_path, frames=300, batch=300, discrete=True)
    torch.manual_seed(0)
    algorithm = MaskedIppoConfig.get_from_yaml() if masked else IppoConfig.get_from_yaml()
    experiment = Experiment(
        task=BbbenchTask.MULTIBALANCE_V1.get_from_yaml(),
        algorithm_config=algorithm,
        model_config=MlpConfig.get_from_yaml(),
        critic_model_config=MlpConfig.get_from_yaml(),
        seed=0,
        config=config,
    )
    batch = next(iter(experiment.collector)).detach()
    # What BenchMARL's loop leaves out of a group's batch: the infos (one group here).
    batch = batch.exclude("info", ("bot", "info"), ("next", "bot", "info"))
    batch = experiment.algorithm.process_batch("bot", batch)
    fallen = ~batch.get(("bot", "mask"))  # (steps, bots): no longer playing
    assert fallen.any()  # random play: bots fall within 300 steps
    gradient = policy_gradient(experiment, batch)
    changed = batch.clone()
    noise = torch.randn_like(changed.get(("bot", "observation")))
    observation = changed.get(("bot", "observation"))
    changed.set(("bot", "observation"), torch.where(fallen[..., None], noise, observation))
    action = changed.get(("bot", "action"))
    changed.set(("bot", "action"), torch.where(fallen, (action + 3) % 9, action))
    same = torch.equal(policy_gradient(experiment, changed), gradient)
    assert same == masked


@pytest.mark.slow
def test_benchmarls_hydra_cli_runs_a_bbbench_task(tmp_path):
    import subprocess
    import sys

    overrides = [
        "algorithm=mappo",
        "task=bbbench/convoy_v0",
        "task.n_bots=2",
        "experiment.max_n_frames=200",
        "experiment.on_policy_collected_frames_per_batch=200",
        "experiment.on_policy_n_envs_per_worker=1",
        "experiment.evaluation=false",
        "experiment.loggers=[]",
        "experiment.sampling_device=cpu",
        "experiment.train_device=cpu",
        "experiment.create_json=false",
        "experiment.checkpoint_interval=0",
        "experiment.render=false",
        f"hydra.run.dir={tmp_path}",
    ]
    result = subprocess.run(
        [sys.executable, "-m", "bbbench.marl.run", *overrides],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert "Task: bbbench/convoy_v0" in result.stdout
    assert "n_bots: 2" in result.stdout


def test_the_playing_rows_advantages_are_normalized_and_the_fallen_rows_are_zero():
    from tensordict import TensorDict

    from bbbench.marl.algorithms import mask_advantage

    torch.manual_seed(0)
    advantage = torch.randn(50, 4, 1) * 0.01 + 0.3  # small, biased: the critic lagging
    playing = torch.rand(50, 4) > 0.3
    batch = TensorDict({("bot", "advantage"): advantage, ("bot", "mask"): playing}, [50])
    out = mask_advantage("bot", batch.clone(), normalize=True).get(("bot", "advantage"))
    assert (out[~playing] == 0).all()
    active = out[playing]
    assert abs(float(active.mean())) < 1e-5
    assert abs(float(active.std()) - 1) < 1e-4
    plain = mask_advantage("bot", batch.clone(), normalize=False).get(("bot", "advantage"))
    assert torch.equal(plain, advantage * playing.unsqueeze(-1))

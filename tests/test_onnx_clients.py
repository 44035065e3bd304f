"""Policies from other frameworks reach bbbench as ONNX: a CleanRL-style torch agent
trained here and exported with torch's two exporters, and RLlib's own export."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import onnx
import pytest
import torch
from onnx import numpy_helper

import bbbench
from bbbench.cli import main
from bbbench.policies import export_onnx, load_policy

FLAT = "bbbench/FlatBalance-v1"
RLLIB_FIXTURE = Path(__file__).with_name("data") / "rllib_flatbalance.onnx"


def layer_init(layer, std=2**0.5, bias_const=0.0):  # CleanRL's
    torch.nn.init.orthogonal_(layer.weight, std)
    torch.nn.init.constant_(layer.bias, bias_const)
    return layer


class Agent(torch.nn.Module):
    """CleanRL's ppo.py agent: an actor and a critic, 64 x 64 tanh."""

    def __init__(self, observations: int, actions: int) -> None:
        super().__init__()
        self.critic = torch.nn.Sequential(
            layer_init(torch.nn.Linear(observations, 64)),
            torch.nn.Tanh(),
            layer_init(torch.nn.Linear(64, 64)),
            torch.nn.Tanh(),
            layer_init(torch.nn.Linear(64, 1), std=1.0),
        )
        self.actor = torch.nn.Sequential(
            layer_init(torch.nn.Linear(observations, 64)),
            torch.nn.Tanh(),
            layer_init(torch.nn.Linear(64, 64)),
            torch.nn.Tanh(),
            layer_init(torch.nn.Linear(64, actions), std=0.01),
        )

    def get_action_and_value(self, x, action=None):
        distribution = torch.distributions.Categorical(logits=self.actor(x))
        if action is None:
            action = distribution.sample()
        return action, distribution.log_prob(action), distribution.entropy(), self.critic(x)


def train_briefly(iterations: int = 3, steps: int = 512):
    """CleanRL-style PPO on FlatBalance-v1 behind gymnasium's NormalizeObservation (and
    CleanRL's clip to [-10, 10]): a few updates, seeded."""
    torch.manual_seed(0)
    env = gym.wrappers.NormalizeObservation(bbbench.make(FLAT))
    agent = Agent(5, 9)
    optimizer = torch.optim.Adam(agent.parameters(), lr=2.5e-4, eps=1e-5)
    observation, _ = env.reset(seed=0)
    for _ in range(iterations):
        batch = {key: [] for key in ("obs", "action", "logprob", "reward", "done", "value")}
        for _ in range(steps):
            x = torch.as_tensor(np.clip(observation, -10, 10), dtype=torch.float32)[None]
            with torch.no_grad():
                action, logprob, _, value = agent.get_action_and_value(x)
            observation, reward, terminated, truncated, _ = env.step(int(action))
            step = (x[0], action[0], logprob[0], reward, terminated, value[0, 0])
            for key, item in zip(batch, step, strict=True):
                batch[key].append(item)
            if terminated or truncated:
                observation, _ = env.reset()
        rewards = np.array(batch["reward"], dtype=np.float32)
        dones = np.array(batch["done"], dtype=np.float32)
        returns, running = np.zeros_like(rewards), 0.0
        for t in reversed(range(steps)):
            running = rewards[t] + 0.99 * running * (1.0 - dones[t])
            returns[t] = running
        obs = torch.stack(batch["obs"])
        actions = torch.stack(batch["action"])
        old_logprob = torch.stack(batch["logprob"])
        values = torch.stack(batch["value"])
        returns_t = torch.from_numpy(returns)
        advantages = returns_t - values
        advantages = (advantages - advantages.mean()) / (advantages.std() + 1e-8)
        for _ in range(4):
            _, logprob, entropy, value = agent.get_action_and_value(obs, actions)
            ratio = (logprob - old_logprob).exp()
            policy_loss = torch.max(-advantages * ratio, -advantages * ratio.clamp(0.8, 1.2)).mean()
            loss = (
                policy_loss + 0.5 * ((value[:, 0] - returns_t) ** 2).mean() - 0.01 * entropy.mean()
            )
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
    statistics = env.obs_rms
    return agent, statistics.mean, np.sqrt(statistics.var + 1e-8)


@pytest.fixture(scope="module")
def cleanrl(tmp_path_factory):
    agent, mean, std = train_briefly()
    folder = tmp_path_factory.mktemp("cleanrl")
    files = {}
    for dynamo in (False, True):
        path = folder / f"cleanrl-{'dynamo' if dynamo else 'torchscript'}.onnx"
        export_onnx(
            agent.actor,
            FLAT,
            path,
            mean=mean,
            std=std,
            clip=10.0,
            algorithm="PPO (CleanRL)",
            training_steps=3 * 512,
            dynamo=dynamo,
        )
        files[dynamo] = path
    return agent, mean, std, files


def test_a_cleanrl_agent_exported_by_either_exporter_acts_as_torch_does(cleanrl):
    agent, mean, std, files = cleanrl
    rng = np.random.default_rng(0)
    observations = rng.normal(0.0, 1.0, (2000, 5)).astype(np.float32) * np.float32(3)
    normalized = np.clip((observations - mean) / std, -10, 10).astype(np.float32)
    with torch.no_grad():
        expected = agent.actor(torch.from_numpy(normalized)).double().numpy()
    outputs = []
    for path in files.values():
        actor = load_policy(path).actor(FLAT)
        assert actor.greedy
        assert [s.op for s in actor.program.prefix] == ["Normalize"]  # in float64, fused
        outputs.append(actor.program(observations))
        assert np.abs(outputs[-1] - expected).max() < 1e-5
    # The two exporters' graphs compute the same bits.
    assert np.array_equal(outputs[0].view(np.uint32), outputs[1].view(np.uint32))


def test_a_cleanrl_agent_is_scored_alike_from_both_exporters(cleanrl, tmp_path, capsys):
    documents = []
    for path in cleanrl[3].values():
        out = tmp_path / f"{path.stem}.json"
        argv = ["eval", str(path), "--task", FLAT, "--episodes", "3", "--workers", "1"]
        assert main([*argv, "--json", str(out)]) == 0
        documents.append(json.loads(out.read_text()))
    assert documents[0]["policy"]["algorithm"] == "PPO (CleanRL)"
    assert documents[0]["tasks"][0]["episodes"] == documents[1]["tasks"][0]["episodes"]


def rllib_reference(path: Path, observations: np.ndarray) -> np.ndarray:
    """RLlib's fully connected network, in float64 from the file's own weights: its
    graph's Gemm nodes in order (tanh between them), whatever RLlib names the tensors."""
    model = onnx.load_model_from_string(path.read_bytes())
    weights = {t.name: numpy_helper.to_array(t).astype(np.float64) for t in model.graph.initializer}
    layers = [node.input[1:] for node in model.graph.node if node.op_type == "Gemm"]
    assert len(layers) == 3  # two hidden layers and the logits
    x = observations.astype(np.float64)
    for k, (weight, bias) in enumerate(layers):
        x = x @ weights[weight].T + weights[bias]  # Gemm with transB=1, as torch's Linear
        x = np.tanh(x) if k < len(layers) - 1 else x
    return x


def test_rllibs_own_export_is_refused_as_it_is_then_scored_through_bbbench_export(tmp_path, capsys):
    contract = ["--observation", "5", "--action-space", "Discrete(9)"]
    code = main(["eval", str(RLLIB_FIXTURE), "--task", FLAT, *contract])
    err = capsys.readouterr().err
    assert code == 2
    assert "2 graph input(s) and 2 output(s) (obs, state_ins -> output, state_outs)" in err
    out = tmp_path / "rllib.onnx"
    argv = ["export", str(RLLIB_FIXTURE), "--out", str(out), "--output", "output", *contract]
    assert main([*argv, "--algorithm", "PPO (RLlib)", "--training-steps", "400"]) == 0
    policy = load_policy(out)
    assert policy.algorithm == "PPO (RLlib)"
    assert policy.training_steps == 400
    actor = policy.actor(FLAT)
    assert {s.op for s in actor.program.prefix} >= {"Shape", "Reshape"}  # RLlib's flatten
    observations = np.random.default_rng(2).normal(0, 2, (1000, 5)).astype(np.float32)
    assert (
        np.abs(actor.program(observations) - rllib_reference(RLLIB_FIXTURE, observations)).max()
        < 1e-5
    )
    assert main(["eval", str(out), "--task", FLAT, "--episodes", "1", "--workers", "1"]) == 0

"""IPPO-GRU and MAPPO-GRU: BenchMARL's GRU model as the actor, exported with its state.

BenchMARL's own model, stepped as its collection steps it (`is_init` zeroing the state
at an episode's start), gives what its export gives, in torch and in bbbench's
interpreter; the recurrent methods' recipes are refused in one line where they would
train what the board cannot play; and a short real training writes a recurrent file
that `bbbench eval` plays."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import torch
from benchmarl.models import GruConfig
from tensordict import TensorDict
from torchrl.data import Composite, Unbounded

from bbbench.cli import main
from bbbench.marl.models import RecurrentActor
from bbbench.policies import load_policy, onnx_bytes
from bbbench.policies.onnx.policy import OnnxPolicy
from bbbench.policies.onnx.reader import parse_onnx
from bbbench.tasks.suite import agent_spaces
from conftest import one_line_exit_2

TASK = "bbbench/Rendezvous-v0"
BOTS = 4
# A recipe for tests: a GRU of 8, one pass of one world's trajectory a minibatch.
SMALL = """\
bbbench/Rendezvous-v0:
  model: {name: gru, hidden_size: 8, mlp_num_cells: [16]}
  critic_model: {name: mlp, num_cells: [16]}
  experiment:
    on_policy_collected_frames_per_batch: 200
    on_policy_n_envs_per_worker: 2
    on_policy_n_minibatch_iters: 1
    on_policy_minibatch_size: 100
"""


def benchmarls_gru(hidden: int = 8):
    """BenchMARL's `Gru` model, one set of parameters for `BOTS` bots of TASK."""
    observation, action = agent_spaces(TASK, "discrete")
    torch.manual_seed(3)
    config = GruConfig.get_from_yaml()
    config.hidden_size, config.mlp_num_cells = hidden, [16]
    return config.get_model(
        input_spec=Composite(
            bot=Composite(observation=Unbounded((BOTS, observation.shape[0])), shape=(BOTS,))
        ),
        output_spec=Composite(
            bot=Composite(logits=Unbounded((BOTS, int(action.n))), shape=(BOTS,))
        ),
        agent_group="bot",
        input_has_agent_dim=True,
        n_agents=BOTS,
        centralised=False,
        share_params=True,
        device="cpu",
        action_spec=Composite(),
    )


def test_benchmarls_gru_steps_as_its_export_does_in_torch_and_in_the_interpreter():
    """Over 40 steps with an episode starting again at step 25, BenchMARL's collection,
    `RecurrentActor` (torch.nn.GRU) and the exported file agree on every state (to
    float32's last bits) and every action."""
    model = benchmarls_gru().eval()
    actor = RecurrentActor(model).eval()
    assert actor.state_width == 8
    content = onnx_bytes(actor, TASK, algorithm="IPPO-GRU", state_width=8)
    played = OnnxPolicy(parse_onnx(content, "gru.onnx", "gru.onnx")).actor(TASK)
    width = agent_spaces(TASK, "discrete")[0].shape[0]
    rng = np.random.default_rng(4)
    hidden = torch.zeros(1, BOTS, 1, 8)
    exported, states = torch.zeros(BOTS, 8), played.initial_state(BOTS)
    for step in range(40):
        obs = rng.normal(size=(BOTS, width)).astype(np.float32)
        if step == 25:  # a new episode: BenchMARL zeroes the state, the play loops start at zeros
            exported, states = torch.zeros(BOTS, 8), played.initial_state(BOTS)
        data = TensorDict(
            {
                ("bot", "observation"): torch.from_numpy(obs)[None],
                "is_init": torch.tensor([[step in (0, 25)]]),
                ("bot", "_hidden_gru_0"): hidden,
            },
            batch_size=(1,),
        )
        with torch.no_grad():
            out = model(data)
            scores, exported = actor(torch.from_numpy(obs), exported)
        hidden = out.get(("next", "bot", "_hidden_gru_0"))
        np.testing.assert_allclose(exported.numpy(), hidden[0, :, 0].numpy(), rtol=0, atol=1e-6)
        logits = out.get(("bot", "logits"))[0]
        np.testing.assert_allclose(scores.numpy(), logits.numpy(), rtol=0, atol=1e-6)
        actions, states = played.step(obs, states)
        np.testing.assert_allclose(states, exported.numpy(), rtol=0, atol=2e-6)
        assert actions == logits.numpy().argmax(axis=1).tolist()


def test_a_gru_of_two_layers_or_per_bot_parameters_is_not_exported():
    model = benchmarls_gru()
    model.n_layers = 2
    with pytest.raises(ValueError, match="one GRU layer shared by every bot"):
        RecurrentActor(model)


@pytest.mark.parametrize(
    ("algorithm", "change", "expected"),
    [
        ("ippo", ("name: gru, hidden_size: 8, mlp_num_cells: [16]", "name: gru"), "ippo-gru"),
        ("ippo-gru", ("name: gru, hidden_size: 8, mlp_num_cells: [16]", "name: mlp"), "name: gru"),
        ("ippo-gru", ("{name: mlp, num_cells: [16]}", "{name: gru}"), "GRU critic"),
        ("ippo-gru", ("hidden_size: 8", "hidden_size: 8, n_layers: 2"), "one layer"),
        ("ippo-gru", ("hidden_size: 8", "hidden_size: 8, dropout: 0.1"), "not 'dropout'"),
        ("ippo-gru", ("[16]}\n  critic", "[16], mlp_activation_class: Mish}\n  critic"), "Mish"),
        ("mappo-gru", ("{name: mlp, num_cells: [16]}", "{name: neighbour_encoder}"), "centralised"),
    ],
)
def test_a_recurrent_recipe_the_board_could_not_play_is_one_line(
    tmp_path, capsys, algorithm, change, expected
):
    text = SMALL.replace(*change)
    assert text != SMALL
    recipe = tmp_path / "recipe.yml"
    recipe.write_text(text)
    out = tmp_path / "policy.onnx"
    argv = ["train", TASK, "--algo", algorithm, "--recipe", str(recipe), "--out", str(out)]
    assert expected in one_line_exit_2(capsys, *argv)
    assert not out.exists()


@pytest.mark.slow
def test_ippo_gru_trains_and_writes_a_recurrent_policy_eval_plays(tmp_path):
    recipe = tmp_path / "recipe.yml"
    recipe.write_text(SMALL)
    out = tmp_path / "policy.onnx"
    argv = ["train", TASK, "--algo", "ippo-gru", "--recipe", str(recipe), "--out", str(out)]
    assert main([*argv, "--steps", "400", "--eval-episodes", "2"]) == 0
    policy = load_policy(out)
    assert policy.algorithm == "IPPO-GRU"
    assert policy.contract.state == 8
    assert policy.contract.training_steps == 400
    record = json.loads((tmp_path / "train.json").read_text())
    assert record["recipe"]["model"]["name"] == "gru"
    scored = tmp_path / "scored.json"
    argv = ["eval", str(out), "--task", TASK, "--episodes", "2", "--workers", "1"]
    assert main([*argv, "--json", str(scored)]) == 0
    (scored_task,) = json.loads(scored.read_text())["tasks"]
    (trained_task,) = json.loads((tmp_path / "results.json").read_text())["tasks"]
    assert scored_task == trained_task
    # The same seed in another process, its worlds in two workers: the same bytes.
    again = tmp_path / "again" / "policy.onnx"
    again.parent.mkdir()
    argv = ["train", TASK, "--algo", "ippo-gru", "--recipe", str(recipe), "--out", str(again)]
    command = [sys.executable, "-m", "bbbench", *argv, "--steps", "400", "--workers", "2"]
    subprocess.run([*command, "--eval-episodes", "2"], check=True, capture_output=True)
    assert again.read_bytes() == out.read_bytes()

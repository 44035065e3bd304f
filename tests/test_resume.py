"""A BenchMARL training in segments (a recipe's `segments`) resumes where it was stopped
and writes the same bytes as the same training never stopped, in another process; a
stopped training of another kind in its folder is refused in one line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch
from test_marl_training import SMALL, TASK, bbbench_cli, small_recipe, untimed
from test_recurrent_training import SMALL as GRU_SMALL
from test_recurrent_training import TASK as GRU_TASK

from bbbench.cli import main
from bbbench.training.benchmarl.recipes import marl_recipe
from bbbench.training.benchmarl.segments import RESUME_FILE, Segments, segment_seed
from bbbench.training.benchmarl.train import actor_network, observation_statistics, train_marl
from conftest import one_line_exit_2

SEGMENTED = SMALL + "  segments: {frames: 400}\n"
# A recurrent training resumes too: each segment starts every world and bot's state anew.
GRU_SEGMENTED = GRU_SMALL + "  segments: {frames: 400}\n"
STEPS = ["--steps", "800", "--eval-episodes", "2"]


class Stop(KeyboardInterrupt):
    """Ctrl-C, at a chosen world step."""


@pytest.mark.parametrize(
    ("algorithm", "task", "text"),
    [
        ("ippo", TASK, SEGMENTED),
        pytest.param("ippo-gru", GRU_TASK, GRU_SEGMENTED, marks=pytest.mark.slow),
    ],
)
def test_a_stopped_training_resumes_to_the_bytes_of_one_never_stopped(
    tmp_path, capsys, algorithm, task, text
):
    plan = small_recipe(tmp_path, text)
    whole = tmp_path / "whole" / "policy.onnx"
    whole.parent.mkdir()
    argv = ["train", task, "--algo", algorithm, "--recipe", plan, "--out", str(whole), *STEPS]
    bbbench_cli(*argv)
    assert not (whole.parent / RESUME_FILE).exists()  # removed when the training ends
    curve = untimed(whole.parent / "curve.json")
    assert [point["steps"] for point in curve] == [200, 400, 600, 800]

    # Stopped in its second segment (600 of 800 world steps): the first one's end is kept.
    stopped = tmp_path / "stopped" / "policy.onnx"
    stopped.parent.mkdir()

    def stop_at_600(steps: int, total: int, point: dict | None) -> None:
        if steps >= 600:
            raise Stop

    with pytest.raises(Stop):
        train_marl(task, algorithm, stopped, steps=800, seed=0, final_episodes=2,
                   on_progress=stop_at_600, recipe_file=plan)  # fmt: skip
    assert (stopped.parent / RESUME_FILE).exists()
    assert not stopped.exists()
    assert not (stopped.parent / "curve.json").exists()

    if algorithm == "ippo":
        assert_segment_loads_what_was_saved(plan, stopped.parent)

    # Another training asked for in its folder is refused; the stopped one is kept.
    argv = ["train", task, "--algo", algorithm, "--recipe", plan, "--out", str(stopped), *STEPS]
    refused = one_line_exit_2(capsys, *argv, "--seed", "1")
    assert "a stopped training of another seed (0, asked for 1)" in refused
    assert "remove the file to start this one afresh" in refused
    assert (stopped.parent / RESUME_FILE).exists()

    # The same command again resumes at 400 and ends where the whole run ended.
    assert main(argv) == 0
    assert stopped.read_bytes() == whole.read_bytes()
    assert untimed(stopped.parent / "curve.json") == curve
    record = json.loads((stopped.parent / "train.json").read_text())
    assert record["resumed_at"] == [400]
    assert record["recipe"]["segments"] == {"frames": 400}
    assert not (stopped.parent / RESUME_FILE).exists()


def assert_segment_loads_what_was_saved(plan: str, folder: Path) -> None:
    """The next segment's experiment, built anew on its own seed, holds the saved models
    (in the policy its collector plays and the one exported) and optimizer steps."""
    segments = Segments(400, 800, folder, fingerprint={})
    saved = segments.read_back()
    assert saved["frames"] == 400
    recipe = marl_recipe("ippo", TASK, plan)
    task = recipe.task_config()
    task.observation_normalization = observation_statistics(
        TASK, task.env_kwargs, 0, recipe.action_mode
    )
    experiment = recipe.build_experiment(task, segment_seed(0, 1), 400, 2, folder)
    fresh = [p.clone() for p in experiment.collector.policy.parameters()]
    optimizer = experiment.optimizers["bot"]["loss_objective"]
    assert optimizer.state_dict()["state"] == {}
    segments.load(experiment, saved)
    prefix = "actor_network_params.module.0.net."  # the loss's name of the actor's network
    actor = {
        key.removeprefix(prefix): value
        for key, value in saved["losses"]["bot"].items()
        if key.startswith(prefix)
    }
    assert actor
    played = dict(experiment.collector.policy.named_parameters())
    exported = actor_network(experiment).state_dict()
    for name, value in actor.items():
        assert torch.equal(played[f"module.0.module.0.net.{name}"], value), name
        assert torch.equal(exported[name], value), name
    assert any(not torch.equal(a, b) for a, b in zip(fresh, played.values(), strict=True))
    steps = [int(s["step"]) for s in optimizer.state_dict()["state"].values()]
    assert steps  # Adam's moments and steps: two batches of two minibatches
    assert steps == [4] * len(steps)
    assert experiment.total_frames == 400
    experiment.close()


def test_each_segment_after_the_first_is_seeded_anew_from_the_training_seed():
    assert segment_seed(7, 0) == 7  # one segment: the training as it was without segments
    seeds = [segment_seed(7, index) for index in range(1, 50)]
    assert len(set(seeds)) == 49
    assert all(0 <= s < 2**30 for s in seeds)
    assert seeds == [segment_seed(7, index) for index in range(1, 50)]
    assert segment_seed(8, 1) != segment_seed(7, 1)


def test_a_resume_file_bbbench_did_not_write_exits_2_with_one_line(tmp_path, capsys):
    plan = small_recipe(tmp_path, SEGMENTED)
    out = tmp_path / "policy.onnx"
    (tmp_path / RESUME_FILE).write_bytes(b"not a training")
    argv = ["train", TASK, "--algo", "ippo", "--recipe", plan, "--out", str(out), *STEPS]
    assert "not a stopped training bbbench can resume" in one_line_exit_2(capsys, *argv)
    assert not out.exists()
    assert (tmp_path / RESUME_FILE).read_bytes() == b"not a training"


@pytest.mark.parametrize(
    ("segments", "expected"),
    [
        ("{frames: 300}", "frames 300 is not a whole number of batches of 200 world steps"),
        ("{frames: 100}", "frames 100: expected a whole number of world steps, at least a batch"),
        ("{frame: 400}", "unknown key 'frame'; it takes frames"),
    ],
)
def test_a_bad_segment_length_exits_2_with_one_line(tmp_path, capsys, segments, expected):
    plan = small_recipe(tmp_path, SMALL + f"  segments: {segments}\n")
    out = tmp_path / "policy.onnx"
    argv = ["train", TASK, "--algo", "ippo", "--recipe", plan, "--out", str(out), *STEPS]
    assert expected in one_line_exit_2(capsys, *argv)
    assert not out.exists()

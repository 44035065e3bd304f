"""The defects a new-user audit of the newer surfaces found (issue 51's table), each
held by a test: one line and exit code 2, with nothing written, or the right record."""

from __future__ import annotations

import json
import shutil
import sys
from importlib import resources

import pytest
import yaml

from bbbench.cli import main
from bbbench.cli.sweep import distinct_labels
from bbbench.training.recipe_files import recipe_file
from conftest import FLAT, one_line_exit_2

LATEST_FLAT = "bbbench/FlatBalance-v1"  # a task with recipes

BEAM = "bbbench/BeamCarry-v0"
REFERENCE_ZIP = resources.files("bbbench.policies") / "reference.zip"


@pytest.mark.parametrize("name", ["curve.json", "train.json", "results.json"])
def test_1_a_policy_named_as_a_log_is_refused_before_training(tmp_path, capsys, name):
    out = tmp_path / name
    err = one_line_exit_2(capsys, "train", LATEST_FLAT, "--algo", "ppo", "--out", str(out))
    assert f"--out {out}: PPO writes a zip policy: give a file name ending in .zip" in err
    assert list(tmp_path.iterdir()) == []


def test_7_a_zip_policy_named_onnx_is_refused_before_training(tmp_path, capsys):
    out = tmp_path / "ppo.onnx"
    err = one_line_exit_2(
        capsys, "train", LATEST_FLAT, "--algo", "ppo", "--seeds", "0,1", "--out", str(out)
    )
    assert "give a file name ending in .zip" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "argv",
    [
        ["eval", "pd", "--task", FLAT],
        ["sweep", "pd", "--task", FLAT, "--axis", "payload_mass", "--values", "0,1"],
        ["train", LATEST_FLAT, "--algo", "ppo", "--seeds", "0,1"],
    ],
)
def test_8_ray_not_installed_is_one_line_naming_the_extra(tmp_path, capsys, monkeypatch, argv):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` fails, as without the extra
    monkeypatch.chdir(tmp_path)
    err = one_line_exit_2(capsys, *argv, "--backend", "ray")
    assert 'pip install "bbbench[ray]"' in err
    assert list(tmp_path.iterdir()) == []


def _recipe(tmp_path, algorithm: str, task_id: str, **changes) -> str:
    entry = yaml.safe_load(recipe_file(algorithm).read_text())[task_id]
    for section, value in changes.items():
        entry[section] = value
    path = tmp_path / "recipe.yml"
    path.write_text(yaml.safe_dump({task_id: entry}))
    return str(path)


def test_9_a_misspelt_recipe_key_is_one_line_with_the_keys_there_are(tmp_path, capsys):
    entry = yaml.safe_load(recipe_file("ppo").read_text())[LATEST_FLAT]
    entry["learning_rte"] = entry.pop("learning_rate")
    (tmp_path / "recipe.yml").write_text(yaml.safe_dump({LATEST_FLAT: entry}))
    out = tmp_path / "policy.zip"
    argv = ["train", LATEST_FLAT, "--algo", "ppo", "--recipe", str(tmp_path / "recipe.yml")]
    err = one_line_exit_2(capsys, *argv, "--out", str(out))
    assert "unknown key 'learning_rte'. Did you mean 'learning_rate'?" in err
    assert "n_steps" in err  # the keys PPO's recipes take
    assert not out.exists()


@pytest.mark.parametrize(("task_id", "bots"), [(BEAM, 9), ("bbbench/MultiBalance-v1", 99)])
def test_10_a_marl_recipe_with_bots_the_task_refuses_is_one_line(tmp_path, capsys, task_id, bots):
    pytest.importorskip("benchmarl")
    plan = _recipe(tmp_path, "ippo", task_id, task={"n_bots": bots, "workers": 1})
    out = tmp_path / "policy.onnx"
    err = one_line_exit_2(
        capsys, "train", task_id, "--algo", "ippo", "--recipe", plan, "--out", str(out)
    )
    assert f"recipe.yml, {task_id}, task:" in err
    assert f"got {bots}" in err
    assert not out.exists()


@pytest.mark.parametrize(("policy", "task_id"), [("team", BEAM), ("pd", LATEST_FLAT)])
def test_5_a_controller_asked_to_sample_is_refused_not_labelled_sampled(capsys, policy, task_id):
    err = one_line_exit_2(capsys, "eval", policy, "--task", task_id, "--stochastic")
    assert f"{policy}: it acts deterministically only" in err
    assert "drop --stochastic" in err


def test_3_two_policies_with_one_file_name_are_told_apart_by_their_folders(tmp_path, capsys):
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        shutil.copyfile(REFERENCE_ZIP, tmp_path / folder / "policy.zip")
    given = [str(tmp_path / "a" / "policy.zip"), str(tmp_path / "b" / "policy.zip")]
    plot = tmp_path / "sweep.svg"
    argv = ["sweep", *given, "--axis", "payload_mass", "--values", "0,1", "--episodes", "1"]
    assert main([*argv, "--workers", "1", "--plot", str(plot)]) == 0
    stdout = capsys.readouterr().out
    figure = plot.read_text()  # text kept as text (svg.fonttype none)
    for label in ("a/policy.zip", "b/policy.zip"):
        assert f"{label} (PPO)" in stdout
        assert label in figure
    assert distinct_labels(["pd", "x/y/policy.zip", "z/y/policy.zip"]) == [
        "pd",
        "x/y/policy.zip",
        "z/y/policy.zip",
    ]


# -- confusing, mended -------------------------------------------------------------------


def test_export_names_the_input_file_for_its_faults(tmp_path, capsys):
    from onnx import TensorProto, helper

    node = helper.make_node("Softmax", ["obs"], ["scores"])
    graph = helper.make_graph(
        [node],
        "g",
        [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", 5])],
        [helper.make_tensor_value_info("scores", TensorProto.FLOAT, ["batch", 5])],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    path = tmp_path / "softmax.onnx"
    path.write_bytes(model.SerializeToString())
    argv = ["--observation", "5", "--action-space", "Discrete(5)"]
    err = one_line_exit_2(capsys, "export", str(path), "--out", str(tmp_path / "o.onnx"), *argv)
    assert err.startswith(f"bbbench: error: {path}: operator 'Softmax'")
    assert "exported graph" not in err


def test_a_team_task_offers_the_keywords_it_takes_and_says_where_its_payload_goes():
    import bbbench
    from bbbench.evaluation.sweep import unit

    with pytest.raises(TypeError) as refused:
        bbbench.make_parallel(BEAM, foo=1)
    offered = str(refused.value)
    assert "payload_mass" in offered
    assert "com_offset" not in offered
    assert "sensor_noise" not in offered
    assert unit("payload_mass", [BEAM]) == "kg at the beam's centre"
    assert unit("payload_mass", [LATEST_FLAT]) == "kg on the torso"
    assert unit("payload_mass", [LATEST_FLAT, BEAM]) == "kg on the torso or kg at the beam's centre"


def test_an_empty_track_draws_its_figures_without_warnings():
    import warnings

    from bbbench.leaderboard.plots import per_task_scores, performance_profiles

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert "<svg" in performance_profiles([])
        assert "<svg" in per_task_scores([], ["bbbench/FlatBalance-v1"])


@pytest.mark.parametrize("episodes", ["0", "-1", "101"])
@pytest.mark.parametrize("seeds", [[], ["--seeds", "0,1"]])
def test_66_eval_episodes_outside_the_seeds_are_refused_before_training(
    tmp_path, capsys, episodes, seeds
):
    out = tmp_path / "policy.zip"
    argv = ["train", LATEST_FLAT, "--algo", "ppo", "--eval-episodes", episodes, *seeds]
    err = one_line_exit_2(capsys, *argv, "--out", str(out))
    assert f"--eval-episodes {episodes}: expected 1 to 100" in err
    assert list(tmp_path.iterdir()) == []


def test_66_rollout_without_a_task_plays_one_the_policy_fits(capsys):
    assert main(["rollout", "--policy", "steer", "--episodes", "1"]) == 0
    assert "bbbench/SteerTracking-v0: 1 episode(s) of the 'steer' policy" in capsys.readouterr().out
    assert main(["rollout", "--episodes", "1"]) == 0  # pd: FlatBalance, as before
    assert capsys.readouterr().out.startswith("bbbench/FlatBalance-v1: 1 episode(s)")


def test_66_a_batched_env_refuses_a_render_mode_it_cannot_honour():
    from bbbench.envs.factory import make_batched

    with pytest.raises(ValueError, match="a batched env does not render; watch one world"):
        make_batched("bbbench/Swap-v0", worlds=2, render_mode="rgb_array")


@pytest.mark.parametrize(
    ("task_id", "wants", "scan"),
    [
        ("bbbench/SteerTracking-v0", "wants Box(9,) ->", False),
        ("bbbench/Waypoints-v0", "wants Box(14,) ->", False),
        ("bbbench/LeggedBumps-v0", "wants Box(17,) (wheel-legged:", True),
    ],
)
def test_66_a_refusal_states_the_tasks_own_observation(task_id, wants, scan):
    from bbbench.policies import load_policy

    reason = load_policy(str(REFERENCE_ZIP)).mismatch(task_id)
    assert wants in reason
    assert ("with height_scan=True" in reason) == scan


def test_66_a_recipe_that_is_not_yaml_is_refused_in_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.yml"
    bad.write_text("bbbench/FlatBalance-v1:\n  gamma: [0.99\n  n_envs: 4\n")
    out = tmp_path / "policy.zip"
    argv = ["train", LATEST_FLAT, "--algo", "ppo", "--recipe", str(bad), "--out", str(out)]
    err = one_line_exit_2(capsys, *argv)
    assert f"recipe file {bad}: not valid YAML at line" in err
    assert not out.exists()


def test_66_a_log_folder_that_cannot_be_made_is_refused_before_training(tmp_path, capsys):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    out = tmp_path / "policy.zip"
    argv = ["train", LATEST_FLAT, "--algo", "ppo", "--log", str(blocker / "logs")]
    err = one_line_exit_2(capsys, *argv, "--out", str(out))
    assert f"--log {blocker / 'logs'}: cannot make the folder" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-file"]


def test_66_a_batched_env_refuses_a_bad_discrete_action_before_any_world_steps():
    import numpy as np

    from bbbench.envs.factory import make_batched

    actions = np.random.default_rng(0).integers(0, 27, size=(6, 4, 4))
    fresh = make_batched("bbbench/Swap-v0", worlds=4, workers=2)
    fresh.reset(seed=3)
    expected = [fresh.step(step)[0] for step in actions]
    fresh.close()
    env = make_batched("bbbench/Swap-v0", worlds=4, workers=2)
    env.reset(seed=3)
    for bad in (1.99, -0.7, float("nan"), 27, -1):
        with pytest.raises(ValueError, match=f"action {bad!r}: .*no world was stepped"):
            env.step(np.full((4, 4), bad))
    got = [env.step(step)[0] for step in actions]  # as if nothing had been refused
    env.close()
    assert all(np.array_equal(a, b) for a, b in zip(expected, got, strict=True))


def test_66_a_training_never_overwrites_a_policy_or_another_trainings_records(tmp_path, capsys):
    out = tmp_path / "policy.zip"
    out.write_bytes(b"a policy")
    argv = ["train", LATEST_FLAT, "--algo", "ppo", "--steps", "64", "--n-envs", "1"]
    err = one_line_exit_2(capsys, *argv, "--out", str(out))
    assert f"--out {out}: a file is there already" in err
    assert out.read_bytes() == b"a policy"
    (tmp_path / "train.json").write_text("{}")
    err = one_line_exit_2(capsys, *argv, "--out", str(tmp_path / "other.zip"))
    assert "holds another training's records (train.json)" in err
    assert not (tmp_path / "other.zip").exists()
    seeded = tmp_path / "runs" / "policy-s1"
    seeded.mkdir(parents=True)
    (seeded / "policy.zip").write_bytes(b"seed 1")
    err = one_line_exit_2(
        capsys, *argv, "--seeds", "0,1", "--out", str(tmp_path / "runs" / "policy.zip")
    )
    assert "a file is there already" in err
    assert (seeded / "policy.zip").read_bytes() == b"seed 1"
    assert not (tmp_path / "runs" / "policy-s0").exists()


def test_66_tasks_whose_observations_differ_are_refused_before_training(tmp_path, capsys):
    out = tmp_path / "policy.zip"
    argv = ["train", "bbbench/SteerTracking-v0", "bbbench/Waypoints-v0", "--algo", "ppo"]
    err = one_line_exit_2(capsys, *argv, "--out", str(out))
    assert "bbbench/SteerTracking-v0 9 values, bbbench/Waypoints-v0 14 values" in err
    assert list(tmp_path.iterdir()) == []
    # the generalist's mix shares one layout and is taken
    from bbbench.training import check_request

    mix = ["bbbench/FlatBalance-v1", "bbbench/Bumps-v2", "bbbench/Slopes-v2"]
    assert check_request(mix, "ppo", None, None)[0] == mix


def test_66_an_n_bots_sweep_plays_the_grid_values_each_task_takes(tmp_path):
    from bbbench.evaluation.sweep import applying_tasks, standard_grid

    assert standard_grid("n_bots") == (2, 4, 8, 16)
    assert standard_grid("n_bots", ["bbbench/MultiBalance-v1"]) == (2, 4, 8, 16)
    assert standard_grid("n_bots", ["bbbench/Swap-v0"]) == (2, 4, 8)
    assert standard_grid("n_bots", ["bbbench/Swap-v0", "bbbench/ConvoyTurns-v0"]) == (2, 4)
    assert {"bbbench/Swap-v0", "bbbench/ConvoyTurns-v0"} <= set(applying_tasks("n_bots"))
    document = tmp_path / "sweep.json"
    argv = ["sweep", "random", "--task", "bbbench/ConvoyTurns-v0", "--axis", "n_bots"]
    assert main([*argv, "--episodes", "1", "--json", str(document)]) == 0
    written = json.loads(document.read_text())
    assert written["values"] == [2, 4]
    assert written["standard_grid"] is True


@pytest.mark.parametrize(
    ("task_id", "scans"), [("bbbench/SteerTracking-v0", False), ("bbbench/FlatBalance-v1", True)]
)
def test_66_the_unknown_keyword_error_lists_height_scan_only_where_it_is_taken(task_id, scans):
    import bbbench

    with pytest.raises(TypeError, match="accepted keyword arguments are") as raised:
        bbbench.make(task_id, foo=1)
    assert ("height_scan" in str(raised.value)) == scans
    if not scans:
        with pytest.raises(ValueError, match="observes no height scan"):
            bbbench.make(task_id, height_scan=True)

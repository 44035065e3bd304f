"""Bad input found by trying the CLI and the envs as a new user would: each mistake gets a
clear error (exit 2 from the CLI, one line) or, where refusing is not possible, a warning;
nothing is lost or half-written."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import bbbench
from bbbench import evaluation
from bbbench.cli import main
from bbbench.evaluation import sweep as sweep_module
from bbbench.leaderboard import submit
from bbbench.leaderboard.submissions import SubmissionError
from conftest import one_line_exit_2

MULTI = "bbbench/MultiBalance-v1"


def never(*args, **kwargs):
    raise AssertionError("an episode was played before the command's options were checked")


def test_eval_refuses_two_outputs_naming_one_file_before_playing(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(evaluation, "evaluate", never)
    same = str(tmp_path / "same.gif")
    err = one_line_exit_2(capsys, "eval", "pd", "--json", same, "--video", same)
    assert "--json and --video both name" in err
    assert not (tmp_path / "same.gif").exists()


def test_sweep_refuses_two_outputs_naming_one_file_before_playing(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(sweep_module, "sweep", never)
    err = one_line_exit_2(
        capsys, "sweep", "pd", "--axis", "push", "--json", "s.svg", "--plot", "./s.svg"
    )
    assert "--json and --plot both name" in err


def test_sweep_refuses_underscores_in_numbers_and_a_policy_given_twice(capsys, monkeypatch):
    monkeypatch.setattr(sweep_module, "sweep", never)
    err = one_line_exit_2(capsys, "sweep", "pd", "--axis", "push", "--values", "1_0")
    assert "'1_0' is not a number" in err
    err = one_line_exit_2(capsys, "sweep", "pd", "pd", "--axis", "push")
    assert "pd is given twice" in err


@pytest.mark.parametrize("value", [2.5, "10", True, 0])
def test_a_wrong_time_limit_names_the_parameter(value):
    with pytest.raises(ValueError, match=r"max_episode_steps must be a whole number of steps"):
        bbbench.make_parallel(MULTI, max_episode_steps=value)


def test_numpy_integers_make_the_time_limit():
    env = bbbench.make_parallel(MULTI, max_episode_steps=np.int64(10))
    assert env.task.max_episode_steps == 10
    assert env.task == bbbench.make_parallel(MULTI, max_episode_steps=10).task


def test_every_real_number_type_is_accepted_alike_and_bool_is_refused():
    numpy_made = bbbench.make(
        "bbbench/FlatBalance-v1",
        payload_mass=np.float32(2.0),
        friction=np.float32(0.5),
        motor_strength=np.int64(3),
        action_delay=np.int64(2),
    ).unwrapped.task
    plain = bbbench.make(
        "bbbench/FlatBalance-v1", payload_mass=2, friction=0.5, motor_strength=3, action_delay=2
    ).unwrapped.task
    assert numpy_made == plain
    assert numpy_made.fingerprint == plain.fingerprint
    for keyword in ("payload_mass", "action_delay"):
        with pytest.raises(ValueError, match=rf"{keyword} must be"):
            bbbench.make("bbbench/FlatBalance-v1", **{keyword: True})
        with pytest.raises(ValueError, match=rf"{keyword} must be"):
            bbbench.make("bbbench/FlatBalance-v1", **{keyword: np.bool_(True)})


def test_leaderboard_check_of_an_empty_folder_or_a_file_is_exit_2(tmp_path, capsys):
    err = one_line_exit_2(capsys, "leaderboard", "check", "--root", str(tmp_path))
    assert "not a leaderboard folder" in err
    a_file = tmp_path / "board.json"
    a_file.write_text("{}")
    err = one_line_exit_2(capsys, "leaderboard", "check", "--root", str(a_file))
    assert "is a file" in err


def test_terrain_into_a_missing_directory_names_it_without_temporary_names(capsys):
    err = one_line_exit_2(
        capsys, "terrain", "--task", "bbbench/Bumps-v2", "--out", "/missing/dir/t.obj"
    )
    assert "no directory /missing/dir" in err
    assert ".partial" not in err


def test_leaderboard_add_errors_name_the_folder_the_entry_goes_to(tmp_path, monkeypatch):
    def refuse(folder):
        raise SubmissionError(f"{folder}: refused for the test")

    monkeypatch.setattr(submit, "read_method", refuse)
    with pytest.raises(SubmissionError) as refused:
        submit.add(
            tmp_path,
            "pd",
            "my-pd",
            {
                "name": "PD",
                "authors": ["a"],
                "algorithm": "PD",
                "tracks": ["single"],
                "licence": "MIT",
            },
            {
                "training_seed": None,
                "recipe": {"world_steps": 0, "tasks": [], "file": "none"},
                "command": "built in",
                "wall_time": "none",
                "hardware": "none",
            },
        )
    assert str(refused.value).startswith(f"{tmp_path / 'submissions' / 'my-pd'}: refused")
    assert ".partial" not in str(refused.value)
    assert not (tmp_path / "submissions" / "my-pd").exists()


def test_an_unknown_env_keyword_gets_a_did_you_mean():
    with pytest.raises(TypeError, match=r"did you mean payload_mass\?"):
        bbbench.make("bbbench/FlatBalance-v1", payload_mas=2)
    with pytest.raises(TypeError, match=r"did you mean n_bots\?"):
        bbbench.make_parallel(MULTI, nbots=2)


def test_argparse_mistakes_are_one_line_pointing_to_help(capsys):
    with pytest.raises(SystemExit) as exited:
        main(["eval", "--episodes", "x"])
    err = capsys.readouterr().err
    assert exited.value.code == 2
    assert err.strip().splitlines() == [
        "bbbench eval: error: argument --episodes: invalid int value: 'x' "
        "(see 'bbbench eval --help')"
    ]


def test_unknown_agents_are_listed_and_reset_options_warn_once():
    env = bbbench.make_parallel(MULTI, n_bots=2)
    with pytest.warns(UserWarning, match=r"ignored 'n_bots'"):
        env.reset(seed=0, options={"n_bots": 8})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env.reset(seed=0, options={"n_bots": 8})
    with pytest.raises(ValueError, match=r"unknown agent\(s\) 'bot_9'.*agents bot_0, bot_1$"):
        env.step({"bot_0": 4, "bot_1": 4, "bot_9": 4})


# -- the team tasks ------------------------------------------------------------------------

BEAM = "bbbench/BeamCarry-v0"


def test_a_team_given_a_number_of_bots_it_cannot_take_exits_2(capsys, monkeypatch):
    monkeypatch.setattr(sweep_module, "sweep", never)
    err = one_line_exit_2(
        capsys, "sweep", "team", "--axis", "n_bots", "--values", "5", "--task", BEAM
    )
    assert "n_bots must be from 2 to 4 for the 'beam-carry' scenario" in err
    for n_bots in (5, 1):  # the scenario's range, not any group's (2 to 16)
        with pytest.raises(ValueError, match=r"n_bots must be from 2 to 4"):
            bbbench.make_parallel(BEAM, n_bots=n_bots)


def test_a_perturbation_a_team_task_cannot_take_names_the_task_and_what_it_takes(
    capsys, monkeypatch
):
    monkeypatch.setattr(sweep_module, "sweep", never)
    err = one_line_exit_2(capsys, "sweep", "team", "--axis", "com_offset", "--task", BEAM)
    assert f"com_offset does not apply to {BEAM}: it takes payload_mass, friction" in err
    err = one_line_exit_2(capsys, "sweep", "team", "--axis", "sensor_noise", "--task", BEAM)
    assert "sensor perturbations apply to single-bot tasks only" in err


def test_a_policy_for_another_robot_or_task_kind_on_a_team_task_exits_2(capsys, monkeypatch):
    monkeypatch.setattr(evaluation, "evaluate", never)
    err = one_line_exit_2(capsys, "eval", "legged", "--task", BEAM)
    assert f"{BEAM} plays the two-wheel robot" in err
    err = one_line_exit_2(capsys, "eval", "team", "--task", MULTI)
    assert f"{MULTI} is not a team task; team plays {BEAM}" in err

"""The `bbbench` command: tables and summaries, or a one-line error and exit 2."""

from __future__ import annotations

import subprocess
import sys

import pytest

import bbbench
from bbbench.cli import main
from conftest import FLAT


def test_list_prints_every_task_with_its_fingerprint(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for task_id in bbbench.list_tasks():
        assert task_id in out
        assert bbbench.spec(task_id).fingerprint in out


def test_rollout_prints_a_summary(capsys):
    assert main(["rollout", "--episodes", "2", "--policy", "pd"]) == 0
    out = capsys.readouterr().out
    assert "2/2 episodes reached the time limit" in out
    assert "mean return 149." in out


def test_unknown_task_is_exit_2_with_a_suggestion_and_no_traceback(capsys):
    assert main(["rollout", "--task", "FlatBalance-v0"]) == 2
    err = capsys.readouterr().err
    assert "Did you mean 'bbbench/FlatBalance-v0'" in err
    assert "Traceback" not in err


@pytest.mark.parametrize(
    "argv", [["rollout", "--episodes", "0"], ["rollout", "--policy", "ppo"], ["frobnicate"]]
)
def test_bad_arguments_are_exit_2(argv, capsys):
    try:
        code = main(argv)
    except SystemExit as exit_:  # argparse's own usage errors
        code = exit_.code
    assert code == 2
    assert "Traceback" not in capsys.readouterr().err


def test_python_dash_m_is_the_same_command():
    done = subprocess.run(
        [sys.executable, "-m", "bbbench", "list"], capture_output=True, text=True, check=True
    )
    assert FLAT in done.stdout

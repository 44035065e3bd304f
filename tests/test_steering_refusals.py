"""Issue 52's bad input, each in one place: one line and exit code 2 from the command
(nothing written), or one ValueError line in Python."""

from __future__ import annotations

import gymnasium as gym
import pytest

import bbbench
from conftest import one_line_exit_2


@pytest.mark.parametrize(
    ("policy", "task", "expected"),
    [
        # the published two-wheel robot's nine actions on a steering task
        ("pd", "bbbench/SteerTracking-v0", "SteerTracking-v0 plays the two-wheel-steer robot"),
        ("pd", "bbbench/Swap-v0", "Swap-v0 plays the two-wheel-steer robot"),
        # a steering policy on a published task
        ("steer", "bbbench/FlatBalance-v1", "steer controls the two-wheel-steer robot"),
        ("steer-avoid", "bbbench/MultiBalance-v1", "steer-avoid"),
        # the avoiding law off Swap
        ("steer-avoid", "bbbench/Waypoints-v0", "Waypoints-v0 is not a task of bots each heading"),
    ],
)
def test_the_command_refuses_a_policy_off_its_robot_in_one_line(
    tmp_path, capsys, policy, task, expected
):
    out = tmp_path / "results.json"
    argv = ["eval", policy, "--task", task, "--episodes", "1", "--json", str(out)]
    error = one_line_exit_2(capsys, *argv)
    assert expected in error
    assert "Traceback" not in error
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("make", "expected"),
    [
        (lambda: bbbench.make_parallel("bbbench/Swap-v0", n_bots=1), "n_bots must be from 2 to 8"),
        (lambda: bbbench.make_parallel("bbbench/Swap-v0", n_bots=9), "n_bots must be from 2 to 8"),
        (lambda: gym.make("bbbench/WaypointsBumps-v0", difficulty=1.5), r"in \[0, 1\], got 1.5"),
        (lambda: gym.make("bbbench/WaypointsBumps-v0", difficulty=-0.1), r"got -0.1"),
        (lambda: gym.make("bbbench/Waypoints-v0", difficulty=0.5), "unknown keyword argument"),
    ],
)
def test_python_refuses_a_group_or_patch_out_of_range_in_one_line(make, expected):
    with pytest.raises((ValueError, TypeError), match=expected) as raised:
        make()
    assert "\n" not in str(raised.value)

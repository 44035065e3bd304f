"""The `bbbench` command: tables and summaries, or a one-line error and exit 2."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

import bbbench
from bbbench.cli import main
from conftest import FLAT

REPO = Path(__file__).resolve().parent.parent


def test_list_prints_every_task_with_its_fingerprint(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for task_id in bbbench.list_tasks():
        assert task_id in out
        assert bbbench.spec(task_id).fingerprint in out
    rows = {line.split()[0]: line for line in out.splitlines()[1:]}
    assert rows["bbbench/Bumps-v1"].endswith("(superseded by bbbench/Bumps-v2)")
    assert "superseded" not in rows["bbbench/Bumps-v2"]


def test_rollout_prints_a_summary(capsys):
    assert main(["rollout", "--episodes", "2", "--policy", "pd"]) == 0
    out = capsys.readouterr().out
    assert "2/2 episodes reached the time limit" in out
    assert "mean return 150.00 of at most 150" in out


def test_unknown_task_is_exit_2_with_a_suggestion_and_no_traceback(capsys):
    assert main(["rollout", "--task", "FlatBalance-v0"]) == 2
    err = capsys.readouterr().err
    assert "Did you mean 'bbbench/FlatBalance-v0'" in err
    assert "Traceback" not in err


def test_rollout_plays_a_multi_bot_task_with_a_zip_shared_by_every_bot(capsys):
    folder = REPO / "leaderboards/submissions/ppo-multibalance-v1/runs/s0"
    argv = ["rollout", "--task", "bbbench/MultiBalance-v1", "--policy", str(folder / "policy.zip")]
    argv += ["--vecnormalize", str(folder / "vecnormalize.pkl"), "--episodes", "2", "--seed", "4"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "shared by 4 bots" in out
    rows = [line for line in out.splitlines() if line.split()[:1] in (["4"], ["5"])]
    assert len(rows) == 2
    for row in rows:
        _, _, mean, falls = row.split()[:4]
        bots = dict(re.findall(r"(bot_\d) (-?[\d.]+)", row))
        assert sorted(bots) == ["bot_0", "bot_1", "bot_2", "bot_3"]
        assert float(mean) == pytest.approx(sum(map(float, bots.values())) / 4, abs=0.01)
        fell = re.findall(r"bot_\d -?[\d.]+ \((\d+)\)", row)  # the step each fallen bot fell at
        assert falls == f"{len(fell)}/4"
    assert "mean return per bot" in out


def test_rollout_video_of_a_multi_bot_task_shows_the_group(tmp_path, capsys):
    iio = pytest.importorskip("imageio.v3")
    path = tmp_path / "group.gif"
    argv = ["rollout", "--task", "bbbench/MultiBalance-v1", "--policy", "random"]
    assert main([*argv, "--episodes", "1", "--seed", "3", "--video", str(path)]) == 0
    assert f"wrote {path}" in capsys.readouterr().out
    frames = iio.imread(path)
    assert frames.shape[1:3] == (360, 480)  # the group's camera, not a single bot's


def test_terrain_of_a_multi_bot_task_is_written(tmp_path, capsys):
    path = tmp_path / "square.obj"
    assert main(["terrain", "--task", "bbbench/MultiBumps-v0", "--out", str(path)]) == 0
    assert path.stat().st_size > 0


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
    # The process exits without the interpreter's teardown: its output must be flushed.
    done = subprocess.run(
        [sys.executable, "-m", "bbbench", "list"], capture_output=True, text=True, check=True
    )
    assert FLAT in done.stdout


def test_the_process_exits_with_the_commands_code():
    done = subprocess.run(
        [sys.executable, "-m", "bbbench", "eval", "pd", "--episodes", "0"],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 2
    assert done.stderr.strip().splitlines()[-1] == (
        "bbbench: error: --episodes must be at least 1, got 0"
    )


@pytest.mark.parametrize("task_id", ["bbbench/Bumps-v0", "bbbench/LeggedObstacles-v0"])
def test_terrain_writes_the_episodes_mesh(task_id, tmp_path, capsys):
    out = tmp_path / "terrain.obj"
    assert main(["terrain", "--task", task_id, "--seed", "3", "--out", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out
    env = bbbench.make(task_id)
    env.reset(seed=3)  # the file holds exactly the terrain that episode plays on
    heights = env.unwrapped.scene.ground.heightmap.heights
    vertices = trimesh.load(out, process=False).vertices
    assert np.allclose(np.sort(vertices[:, 2]), np.sort(heights.ravel()), atol=1e-6)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["terrain", "--task", "bbbench/FlatBalance-v0"], "flat ground"),
        (["terrain", "--difficulty", "3"], r"difficulty must be a number in \[0, 1\]"),
        (["terrain", "--task", "Bumps-v0"], "Did you mean 'bbbench/Bumps-v0'"),
    ],
)
def test_terrain_mistakes_are_exit_2(argv, message, tmp_path, capsys):
    assert main([*argv, "--out", str(tmp_path / "t.obj")]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err)
    assert "Traceback" not in err
    assert not (tmp_path / "t.obj").exists()


def test_list_of_one_task_prints_its_description_and_version_history(capsys):
    assert main(["list", "bbbench/NoisySensors-v1"]) == 0
    out = capsys.readouterr().out
    task = bbbench.spec("bbbench/NoisySensors-v1")
    assert out.startswith(f"{task.id}: {task.summary}")
    assert "| pitch       | N(0, 0.1) rad" in out  # the description, its table whole
    assert all(entry in out for entry in task.version_history)
    assert task.fingerprint in out
    assert main(["list", "bbbench/NoisySensors-v0"]) == 0
    assert "superseded by bbbench/NoisySensors-v1" in capsys.readouterr().out


def test_list_of_an_unknown_task_is_exit_2(capsys):
    assert main(["list", "Noisy"]) == 2
    err = capsys.readouterr().err
    assert "unknown task 'Noisy'" in err
    assert "Traceback" not in err


def test_output_to_a_reader_that_left_ends_quietly():
    """`bbbench list | head`: no traceback when the pipe closes first."""
    read, write = os.pipe()
    os.close(read)  # the reader is gone before the command writes
    try:
        ended = subprocess.run(
            [sys.executable, "-m", "bbbench", "list"], stdout=write, stderr=subprocess.PIPE
        )
    finally:
        os.close(write)
    assert ended.returncode == 141
    assert ended.stderr == b""

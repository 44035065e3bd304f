"""`bbbench train --seeds`: one training per seed, here or as Ray tasks, each the same
bytes as a single `--seed` run."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

from bbbench.cli import main
from conftest import one_line_exit_2

FLAT = "bbbench/FlatBalance-v1"
TINY = ["--algo", "ppo", "--steps", "1024", "--eval-episodes", "2"]


@pytest.mark.parametrize(
    ("seeds", "expected"),
    [
        ("0,one", "'one' is not a seed"),
        ("0,-1", "'-1' is not a seed"),
        ("1.5", "'1.5' is not a seed"),
        ("", "'' is not a seed"),
        ("0,0", "a seed is given twice"),
    ],
)
def test_seeds_that_are_not_whole_numbers_exit_2(tmp_path, capsys, seeds, expected):
    out = str(tmp_path / "policy.zip")
    err = one_line_exit_2(capsys, "train", FLAT, *TINY, "--seeds", seeds, "--out", out)
    assert expected in err
    assert list(tmp_path.iterdir()) == []


def test_seed_and_seeds_together_and_a_backend_without_seeds_exit_2(tmp_path, capsys):
    out = str(tmp_path / "policy.zip")
    err = one_line_exit_2(
        capsys, "train", FLAT, *TINY, "--seed", "3", "--seeds", "0,1", "--out", out
    )
    assert "give one of them" in err
    err = one_line_exit_2(capsys, "train", FLAT, *TINY, "--backend", "ray", "--out", out)
    assert "--seeds" in err


def test_an_unreachable_ray_address_exits_2_within_ten_seconds(tmp_path, capsys):
    out = str(tmp_path / "policy.zip")
    began = time.monotonic()
    argv = ["--seeds", "0", "--backend", "ray", "--address", "127.0.0.1:9", "--out", out]
    err = one_line_exit_2(capsys, "train", FLAT, *TINY, *argv)
    assert time.monotonic() - began < 10
    assert "no Ray cluster answers there" in err


@pytest.mark.slow
def test_a_seed_trained_as_a_ray_task_is_the_local_runs_bytes(tmp_path, capsys):
    """Against `bbbench train --seed 1` in a process of its own, as a user runs it."""
    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir()
    there.mkdir()
    local = ["train", FLAT, *TINY, "--seed", "1", "--out", str(here / "policy.zip")]
    subprocess.run([sys.executable, "-m", "bbbench", *local], check=True, capture_output=True)
    argv = ["--seeds", "1,2", "--backend", "ray", "--out", str(there / "policy.zip")]
    assert main(["train", FLAT, *TINY, *argv]) == 0
    printed = capsys.readouterr().out
    assert "seed 1: wrote" in printed
    assert "seed 2: wrote" in printed
    # Each seed's curve, point by point, as it trains: the last point before its files.
    for seed in (1, 2):
        last = f"seed {seed}: 1,024 of 1,024 steps"
        assert last in printed
        assert printed.index(last) < printed.index(f"seed {seed}: wrote")
    for name in ("policy.zip", "results.json"):  # curve.json and train.json hold wall times
        assert (there / "policy-s1" / name).read_bytes() == (here / name).read_bytes(), name
    assert (there / "policy-s2" / "policy.zip").read_bytes() != (here / "policy.zip").read_bytes()


@pytest.mark.slow
def test_seeds_trained_here_are_each_the_bytes_of_its_own_run(tmp_path, capsys):
    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir()
    there.mkdir()
    local = ["train", FLAT, *TINY, "--seed", "2", "--out", str(here / "policy.zip")]
    subprocess.run([sys.executable, "-m", "bbbench", *local], check=True, capture_output=True)
    argv = ["--seeds", "1,2", "--out", str(there / "policy.zip")]
    assert main(["train", FLAT, *TINY, *argv]) == 0
    printed = capsys.readouterr().out
    assert printed.count("seed 2: 1,024 of 1,024 steps") == 1  # its curve's last point
    for name in ("policy.zip", "results.json"):
        assert (there / "policy-s2" / name).read_bytes() == (here / name).read_bytes(), name


@pytest.mark.slow
def test_an_ippo_seed_on_ray_with_worker_processes_is_the_local_runs_bytes(tmp_path, capsys):
    """The campaign's route: IPPO's seeds as Ray tasks, each stepping its worlds in two
    worker processes, against a local run on one process (a fresh one, as a user's)."""
    from test_marl_training import SMALL, TASK

    recipe = tmp_path / "recipe.yml"
    recipe.write_text(SMALL)
    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir()
    there.mkdir()
    tiny = ["--algo", "ippo", "--recipe", str(recipe), "--steps", "400", "--eval-episodes", "2"]
    local = ["train", TASK, *tiny, "--seed", "1", "--workers", "1"]
    local += ["--out", str(here / "policy.onnx")]
    subprocess.run([sys.executable, "-m", "bbbench", *local], check=True, capture_output=True)
    argv = ["--seeds", "1", "--backend", "ray", "--workers", "2"]
    assert main(["train", TASK, *tiny, *argv, "--out", str(there / "policy.onnx")]) == 0
    for name in ("policy.onnx", "results.json"):
        assert (there / "policy-s1" / name).read_bytes() == (here / name).read_bytes(), name


TWO_IN_ONE = """
import hashlib, sys
from pathlib import Path
from bbbench.training import train

def bytes_of(task, algorithm, seed, folder, **keywords):
    out = Path(folder) / ("policy.onnx" if algorithm in ("ippo", "mappo") else "policy.zip")
    out.parent.mkdir(parents=True, exist_ok=True)
    train([task], algorithm, out=out, seed=seed, final_episodes=1, **keywords)
    return hashlib.sha256(out.read_bytes()).hexdigest()
"""


@pytest.mark.slow
@pytest.mark.parametrize(
    ("task_id", "algorithm", "keywords"),
    [
        ("bbbench/FlatBalance-v1", "ppo", {"steps": 2048, "eval_freq": 1024}),
        ("bbbench/MultiBalance-v1", "ippo", {"steps": 10, "n_envs": 2, "workers": 1}),
    ],
)
def test_two_trainings_in_one_process_give_each_its_own_bytes(
    tmp_path, task_id, algorithm, keywords
):
    # Another training first in this process (MAPPO or PPO, another seed), then seed 1;
    # against seed 1 alone in a fresh process.
    first = "mappo" if algorithm == "ippo" else "ppo"
    script = TWO_IN_ONE + (
        f"print(bytes_of({task_id!r}, {first!r}, 0, sys.argv[1] + '/a', **{keywords!r}))\n"
        f"print(bytes_of({task_id!r}, {algorithm!r}, 1, sys.argv[1] + '/b', **{keywords!r}))\n"
    )
    alone = TWO_IN_ONE + (
        f"print(bytes_of({task_id!r}, {algorithm!r}, 1, sys.argv[1] + '/c', **{keywords!r}))\n"
    )
    runs = [
        subprocess.run(
            [sys.executable, "-c", code, str(tmp_path)],
            capture_output=True,
            text=True,
            check=True,
            timeout=600,
        ).stdout.split()
        for code in (script, alone)
    ]
    (_, second), (only,) = runs
    assert second == only

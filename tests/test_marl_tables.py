"""scripts/marl_tables.py, which writes docs/baselines.md's MARL comparison tables from the
runs' own files: a run that plays exactly the classical controller's episodes ties it."""

from __future__ import annotations

import json
from pathlib import Path

from bbbench.evaluation.results import dumps, read
from conftest import load_script

ROOT = Path(__file__).resolve().parents[1]


def fake_run(folder: Path, results: dict, minutes: float) -> None:
    folder.mkdir(parents=True)
    (folder / "results.json").write_text(json.dumps(results))
    (folder / "train.json").write_text(
        json.dumps({"wall_time_s": minutes * 60, "bot_steps": 1_200_000})
    )


def test_a_run_playing_the_controllers_episodes_ties_it(tmp_path):
    tables = load_script("marl_tables")
    board = ROOT / "leaderboards"
    pd = read(board / "results" / "pd.json")
    worse = json.loads(json.dumps(pd))
    for block in worse["tasks"]:
        for episode in block["episodes"]:
            episode["return"] -= 50.0
            episode["falls"], episode["success"] = 1, False
    fake_run(tmp_path / "x-s0", pd, 20.0)
    fake_run(tmp_path / "x-s2", worse, 21.5)
    line = tables.row(tmp_path, board, "bbbench/MultiBalance-v1", "X", "x")
    cells = [cell.strip() for cell in line.strip("|").split("|")]
    task, method, steps, walls, by_seed, median, whole, probability, classical = cells
    assert (task, method, steps, walls) == ("MultiBalance-v1", "X", "1.2M", "20.0 / - / 21.5 min")
    first, missing, third = by_seed.split(" / ")
    assert first == classical  # the controller's own episodes score as the controller
    assert missing == "-"
    assert float(third) < float(first)
    # Two seeds: the median is their mean, and the median seed is the lower one.
    assert float(median) == round((float(first) + float(third)) / 2, 3)
    assert float(probability.split()[0]) < 0.1  # 50 less an episode: below the controller
    pd_whole = [
        e["success"]
        for b in pd["tasks"]
        if b["task"] == "bbbench/MultiBalance-v1"
        for e in b["episodes"]
    ]
    assert whole == f"{sum(pd_whole) / (2 * len(pd_whole)):.0%}"
    assert tables.row(tmp_path, board, "bbbench/MultiBalance-v1", "Y", "nothing") is None


def test_the_same_episodes_give_one_half(tmp_path):
    tables = load_script("marl_tables")
    board = ROOT / "leaderboards"
    fake_run(tmp_path / "x-s0", read(board / "results" / "pd.json"), 20.0)
    line = tables.row(tmp_path, board, "bbbench/MultiBalance-v1", "X", "x")
    assert "| 0.50 [" in line


def test_versus_pools_the_seeds_and_sets_one_method_against_the_other(tmp_path):
    tables = load_script("marl_tables")
    pd = read(ROOT / "leaderboards" / "results" / "pd.json")
    better = json.loads(json.dumps(pd))
    for block in better["tasks"]:
        for episode in block["episodes"]:
            episode["return"] += 200.0  # above every episode of PD's
    fake_run(tmp_path / "a-s0", better, 20.0)
    fake_run(tmp_path / "a-s1", better, 20.0)
    fake_run(tmp_path / "b-s2", pd, 20.0)
    task = "bbbench/MultiBalance-v1"
    line = tables.versus(tmp_path, task, "A against B", "a", "b")
    assert "| 2 / 1 |" in line
    assert line.endswith("| 1.00 [1.00, 1.00] |")
    same = tables.versus(tmp_path, task, "B against B", "b", "b")
    assert "| 0.50 [" in same  # resampled independently, its interval spans 0.5
    assert tables.versus(tmp_path, task, "A against none", "a", "c") is None


def test_a_run_whose_episodes_the_board_holds_drops_its_copy_and_reads_the_boards(tmp_path):
    """scripts/train_baselines.py removes a run's results.json once the board's results
    hold the same episodes; the tables then read the board's, and give the same row."""
    tables, runs = load_script("marl_tables"), load_script("train_baselines")
    board, task = tmp_path / "board", "bbbench/MultiBalance-v1"
    (board / "results").mkdir(parents=True)
    pd = read(ROOT / "leaderboards" / "results" / "pd.json")
    for name in ("x-s0", "pd"):  # the run's, and the controller's the row compares with
        (board / "results" / f"{name}.json").write_text(dumps(pd))
    fake_run(tmp_path / "x-s0", pd, 20.0)
    before = tables.row(tmp_path, board, task, "X", "x")
    assert runs.drop_repeated_results(tmp_path / "x-s0", board)
    assert not (tmp_path / "x-s0" / "results.json").exists()
    assert tables.row(tmp_path, board, task, "X", "x") == before
    other = json.loads(json.dumps(pd))
    other["tasks"][0]["episodes"][3]["return"] += 1e-9  # not the board's episodes
    fake_run(tmp_path / "y-s0", other, 20.0)
    (board / "results" / "y-s0.json").write_text(dumps(pd))
    assert not runs.drop_repeated_results(tmp_path / "y-s0", board)
    assert (tmp_path / "y-s0" / "results.json").exists()

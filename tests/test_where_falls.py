"""scripts/where_falls.py, which splits a multi-bot policy's lost return into falls and
tracking: it plays the episodes `bbbench eval` plays (the board's falls, seed by seed)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bbbench.evaluation.results import read
from bbbench.tasks.suite import spec
from conftest import load_script

ROOT = Path(__file__).resolve().parents[1]
TASK = "bbbench/MultiBalance-v1"


def test_the_falls_are_the_boards_and_each_is_placed():
    script = load_script("where_falls")
    seeds = list(spec(TASK).eval_seeds[:10])
    counted = script.tally("pd", TASK, seeds)
    board = read(ROOT / "leaderboards" / "results" / "pd.json")
    (block,) = [block for block in board["tasks"] if block["task"] == TASK]
    assert counted.falls == sum(episode["falls"] for episode in block["episodes"][:10]) > 0
    assert all(0 < step < 1500 for step in counted.fall_steps)
    assert all(distance > 0 for distance in counted.fall_distances)
    # Up bot-steps earn the tracking share: at most 0.09 each, and PD tracks.
    assert 0.03 < counted.velocity_reward / counted.bot_steps <= 0.09
    row = counted.row("pd", 4, len(seeds))
    assert row.startswith(f"| pd | {counted.falls} of 40 |")


def test_nearest_reads_the_first_neighbour_slot():
    script = load_script("where_falls")
    observation = np.zeros(17, dtype=np.float32)
    assert script.nearest(observation) == float("inf")  # no bot within range
    observation[5:7] = (3.0, -4.0)
    assert script.nearest(observation) == 5.0


def test_a_team_task_is_refused():
    script = load_script("where_falls")
    with pytest.raises(SystemExit, match="not a crossing task"):
        script.tally("pd", "bbbench/Convoy-v0", [0])

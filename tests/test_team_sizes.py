"""Teams of another size at test time (issue 67): the board's neighbour-encoder policies,
trained with 4 bots, play any number of bots, since each bot reads its K nearest
neighbours in fixed slots."""

from __future__ import annotations

from pathlib import Path

import pytest

import bbbench
from bbbench.evaluation.harness import play_tasks
from bbbench.evaluation.sweep import variant
from bbbench.policies import load_policy

BOARD = Path(__file__).resolve().parents[1] / "leaderboards" / "submissions"


@pytest.mark.parametrize(
    ("method", "task_id"),
    [
        ("ippo-multibalance-v1-3m", "bbbench/MultiBalance-v1"),
        ("mappo-swap-v0-3m", "bbbench/Swap-v0"),
    ],
)
def test_a_neighbour_encoder_policy_plays_every_team_size(method, task_id):
    policy = load_policy(BOARD / method / "runs" / "s0" / "policy.onnx")
    task = bbbench.spec(task_id)
    sizes = (2, 4, 6, 8)
    tasks = [variant(task, "n_bots", size) for size in sizes]
    played = play_tasks(policy, tasks, seeds=[task.eval_seeds[:1]] * len(sizes), workers=1)
    for size, (episode,) in zip(sizes, played.episodes, strict=True):
        assert episode.failure is None, (size, episode.failure)
        assert episode.length > 100, size  # it drives, not only its first step
    assert [t.group.n_bots for t in tasks] == list(sizes)


@pytest.mark.parametrize("size", [1, 9, 17])
def test_a_team_size_outside_the_tasks_range_is_one_clear_line(size):
    with pytest.raises(ValueError, match="n_bots must be") as raised:
        variant(bbbench.spec("bbbench/Swap-v0"), "n_bots", size)
    assert "\n" not in str(raised.value)

"""The crossing tasks' classical controller: PD, the later of two bots at a crossing
stopping and the earlier passing, from the neighbour block of the observation."""

from __future__ import annotations

import numpy as np
import pytest

import bbbench
from bbbench.policies import PDController, load_policy
from bbbench.policies.controllers.crossing import CrossingController


def observation(target: float, *neighbours: tuple[float, float, float, float]) -> np.ndarray:
    """A standing bot at `target` m/s (its wheels at that speed), with `neighbours`
    (right, forward, right_velocity, forward_velocity) and empty slots after them."""
    row = [0.0, 0.0, target / 0.1, target / 0.1, target] + [0.0] * 12
    for k, values in enumerate(neighbours):
        row[5 + 4 * k : 9 + 4 * k] = values
    return np.array(row, dtype=np.float32)


def test_alone_it_is_pd():
    law, pd = CrossingController(), PDController()
    alone = observation(0.5)
    assert law.target(alone) == pytest.approx(0.5)
    assert law(alone) == pd(alone)


def test_the_later_bot_stops_and_the_earlier_passes():
    law = CrossingController()
    # A bot 1 m to the right, 1 m ahead, crossing leftwards at 1 m/s: it reaches this
    # bot's line in 1 s, 1 m ahead; this bot (0.5 m/s) would get there in 2 s: it yields.
    later = observation(0.5, (1.0, 1.0, -1.0, -0.5))
    assert law.target(later) == 0.0
    # The same crossing 0.3 m ahead: this bot gets there in 0.6 s, first: it passes.
    earlier = observation(0.5, (1.0, 0.3, -1.0, -0.5))
    assert law.target(earlier) == pytest.approx(0.65)


@pytest.mark.parametrize(
    "neighbour",
    [
        (1.0, -1.0, -1.0, -0.5),  # crosses behind the bot
        (0.5, 3.0, 0.0, -1.0),  # head-on along the bot's line: crosses nowhere
        (1.0, 1.0, 1.0, -0.5),  # moving away from the bot's line
        (1.0, 4.0, -0.1, -0.5),  # reaches the line after the horizon
    ],
)
def test_no_conflict_keeps_the_target(neighbour):
    assert CrossingController().target(observation(0.5, neighbour)) == pytest.approx(0.5)


def test_it_plays_the_crossing_tasks_only():
    policy = load_policy("crossing")
    assert policy.mismatch("bbbench/MultiBumps-v1") is None
    assert "not a crossing task" in policy.mismatch("bbbench/Convoy-v0")
    assert "plays the wheel-legged robot" in policy.mismatch("bbbench/LeggedFlatBalance-v0")


@pytest.mark.slow
def test_on_the_training_seeds_its_gains_were_chosen_on_it_beats_pd():
    """MultiBalance-v1's training seeds 0-39 (scripts/crossing_gains.py): fewer bots
    fall and the mean return is higher than PD's (the board scores it on eval seeds)."""
    from bbbench.evaluation.episodes import LockstepPlayer

    task, seeds = "bbbench/MultiBalance-v1", list(range(40))
    assert not set(seeds) & set(bbbench.spec(task).eval_seeds)
    falls, returns = {}, {}
    for name in ("pd", "crossing"):
        actor = load_policy(name).actor(task)
        player = LockstepPlayer(actors={task: actor}, action_mode="discrete", sampled=False)
        played = player.play(task, seeds)
        player.close()
        falls[name] = sum(episode.falls for episode in played)
        returns[name] = np.mean([episode.episode_return for episode in played])
    assert falls["crossing"] < falls["pd"]
    assert returns["crossing"] > returns["pd"] + 5.0

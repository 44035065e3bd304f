"""A method is its runs: rliable's statistics over training seeds, every episode counted."""

from __future__ import annotations

import numpy as np
import pytest

from bbbench.evaluation import stats
from bbbench.evaluation.stats import Runs


def episodes(run_means, count=100, spread=0.05, seed=0):
    """(runs, count) scores around each run's mean."""
    rng = np.random.default_rng(seed)
    return np.array([m + spread * rng.standard_normal(count) for m in run_means])


def test_a_runs_falls_count_in_its_score():
    """The worst quarter of a run's episodes (its falls) is not trimmed: the score is the
    mean over every episode."""
    steady = np.full((1, 100), 0.8)
    falling = steady.copy()
    falling[0, :30] = 0.0
    assert Runs((steady,)).point() == pytest.approx(0.8)
    assert Runs((falling,)).point() == pytest.approx(0.56)


def test_the_point_is_the_mean_over_runs_and_tasks_then_the_iqm_from_five_runs():
    three = Runs((episodes([0.2, 0.5, 0.9]), episodes([0.4, 0.4, 0.4])))
    assert three.point() == pytest.approx(np.mean([0.2, 0.5, 0.9, 0.4, 0.4, 0.4]), abs=0.01)
    outlier = [0.5, 0.5, 0.5, 0.5, -5.0]  # one run that diverged
    five = Runs((episodes(outlier, spread=0.0),))
    assert stats.IQM_RUNS == 5
    assert five.point() == pytest.approx(0.5)  # the middle half of 5 runs: 0.5s only


def test_the_interval_covers_seed_to_seed_variation():
    """Two methods with the same episode noise and the same mean: the one whose seeds
    disagree gets the wider interval (an interval from one run's episodes would not)."""
    agreeing = Runs((episodes([0.5, 0.5, 0.5]),))
    disagreeing = Runs((episodes([0.2, 0.5, 0.8]),))
    low, high = agreeing.interval()
    wide_low, wide_high = disagreeing.interval()
    assert low < agreeing.point() < high
    assert wide_high - wide_low > 5 * (high - low)
    assert wide_low < 0.3
    assert wide_high > 0.7


def test_one_run_has_its_episodes_interval():
    controller = Runs((episodes([0.6], spread=0.2),))
    low, high = controller.interval()
    half_width = 1.96 * 0.2 / np.sqrt(100)
    assert high - low == pytest.approx(2 * half_width, rel=0.15)


def test_probability_of_improvement_compares_runs():
    better = Runs((episodes([0.7, 0.75, 0.8]),), seed=1)
    worse = Runs((episodes([0.3, 0.35, 0.4]),), seed=2)
    point, (low, high) = stats.run_improvement(better, worse)
    assert (point, low, high) == (1.0, 1.0, 1.0)
    twin = Runs(better.scores, seed=9)  # the same scores, drawn independently
    same_point, (same_low, same_high) = stats.run_improvement(better, twin)
    assert same_point == 0.5
    assert same_low < 0.5 < same_high
    # One run of three above: P = 1/3 on the point, and the seeds' draws spread it.
    mixed = Runs((episodes([0.2, 0.55, 0.9]),), seed=3)
    point, (low, high) = stats.run_improvement(mixed, Runs((episodes([0.5]),), seed=4))
    assert point == pytest.approx(2 / 3)
    assert low < 0.5 < high


def test_the_statistics_are_the_same_bits_whatever_else_was_computed():
    method = Runs((episodes([0.4, 0.6, 0.5]), episodes([0.1, 0.3, 0.2])), seed=7)
    first = (method.point(), method.interval())
    other = Runs((episodes([0.9, 0.1, 0.5]),), seed=7)
    other.interval()
    stats.run_improvement(other, Runs((episodes([0.2]),)))
    fresh = Runs(tuple(task.copy() for task in method.scores), seed=7)
    assert (fresh.point(), fresh.interval()) == first


def test_methods_draw_from_their_own_seeds():
    assert stats.method_seed("IPPO Swap-v0 3M") == stats.method_seed("IPPO Swap-v0 3M")
    assert stats.method_seed("IPPO Swap-v0 3M") != stats.method_seed("MAPPO Swap-v0 3M")


def test_runs_must_be_the_same_on_every_task():
    with pytest.raises(ValueError, match="same runs"):
        Runs((np.zeros((3, 10)), np.zeros((2, 10))))
    with pytest.raises(ValueError, match=r"\(runs, episodes\)"):
        Runs((np.zeros(10),))
    with pytest.raises(ValueError, match="at least one task"):
        Runs(())


def test_ranks_do_not_chain():
    """A beats C clearly, B is level with both: A and B share rank 1, C is 2nd, not
    pulled up to 1 through B."""
    a = Runs((episodes([0.80, 0.82, 0.84]),), seed=1)
    b = Runs((episodes([0.55, 0.7, 0.85]),), seed=2)
    c = Runs((episodes([0.56, 0.58, 0.60]),), seed=3)
    methods = {"a": a, "b": b, "c": c}
    beaten_by = {
        name: [
            other
            for other, rival in methods.items()
            if other != name and stats.run_improvement(rival, method)[1][0] > 0.5
        ]
        for name, method in methods.items()
    }
    assert beaten_by == {"a": [], "b": [], "c": ["a"]}
    assert stats.ranks(beaten_by) == {"a": 1, "b": 1, "c": 2}

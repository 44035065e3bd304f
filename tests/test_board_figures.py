"""The board's figures: small SVG text that draws what the numbers say."""

from __future__ import annotations

import re

import numpy as np


def test_a_profile_is_drawn_through_its_corners_only_and_the_line_is_the_same():
    from bbbench.leaderboard.plots import THRESHOLDS, _corners, performance_profiles

    scores = np.random.default_rng(3).uniform(0.2, 0.6, size=40)
    profile = (scores[:, None] > THRESHOLDS[None, :]).mean(axis=0)  # flat at 1, then at 0
    xs, ys = _corners(THRESHOLDS, profile)
    assert len(xs) < len(THRESHOLDS) // 2
    assert (xs[0], xs[-1]) == (THRESHOLDS[0], THRESHOLDS[-1])
    np.testing.assert_allclose(np.interp(THRESHOLDS, xs, ys), profile, rtol=0, atol=1e-12)
    page = performance_profiles([("flat", profile)])
    assert page.count("\nL ") < len(THRESHOLDS) // 2  # the SVG's path holds the corners only


def test_the_board_figures_name_one_font_in_each_label():
    from bbbench.leaderboard.plots import per_task_scores

    entry = {
        "submission": {"name": "pd"},
        "tasks": {"bbbench/FlatBalance-v1": {"normalized_score": 0.7, "normalized_ci": [0.6, 0.8]}},
    }
    page = per_task_scores([entry], ["bbbench/FlatBalance-v1"])
    fonts = set(re.findall(r"font-family: ([^;\"]*)", page))
    assert fonts == {"'DejaVu Sans', sans-serif"}

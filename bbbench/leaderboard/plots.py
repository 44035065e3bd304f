"""The leaderboard's figures, drawn by matplotlib as SVG text with the same bytes on every
build: a fixed `svg.hashsalt` for element ids, no date or creator metadata, text kept
as text (`svg.fonttype: none`: small, and no glyph outlines)."""

from __future__ import annotations

import io
from collections.abc import Sequence
from typing import Any

import numpy as np

# rliable's score distributions over this range of normalized score; 0 is the random
# policy, 1 the task's maximum return.
THRESHOLDS = np.linspace(-0.25, 1.0, 126)
_STYLE = {
    "svg.hashsalt": "bbbench",
    "svg.fonttype": "none",
    "font.family": "sans-serif",
    # matplotlib lays text out in its bundled DejaVu Sans whatever this lists, and writes
    # the whole list into every <text> of the SVG: one name keeps each label short.
    "font.sans-serif": ["DejaVu Sans"],
    "font.size": 9,
    "axes.spines.top": False,
    "axes.spines.right": False,
}


def _svg(figure) -> str:
    buffer = io.StringIO()
    figure.savefig(buffer, format="svg", metadata={"Date": None, "Creator": None})
    text = buffer.getvalue()
    return text[text.index("<svg") :].strip()  # inline in HTML: no XML prolog or doctype


def _figure(width: float, height: float):
    from matplotlib.figure import Figure  # lazy: matplotlib, for the board's pages only

    return Figure(figsize=(width, height), layout="constrained")


def _style():
    import matplotlib  # lazy: matplotlib, for the board's pages only

    return matplotlib.rc_context(_STYLE)


def _colors(count: int) -> list:
    import matplotlib  # lazy: matplotlib, for the board's pages only

    palette = matplotlib.colormaps["tab10" if count <= 10 else "tab20"]
    size = 10 if count <= 10 else 20
    return [palette(i % size) for i in range(count)]


def _legend_height(count: int) -> float:
    """Inches a one-column legend of `count` entries takes at the figures' font size."""
    return 0.6 + 0.19 * count


def interval_estimates(entries: Sequence[dict[str, Any]]) -> str:
    """Each method's overall score (over runs x tasks) with its 95% interval, in the
    board's order."""
    with _style():
        figure = _figure(6.0, 0.9 + 0.32 * len(entries))
        axes = figure.add_subplot()
        for row, (entry, color) in enumerate(zip(entries, _colors(len(entries)), strict=True)):
            score = entry["overall"]
            if not score.get("tasks"):
                continue
            low, high = score["normalized_ci"]
            axes.plot([low, high], [row, row], color=color, linewidth=6, alpha=0.55)
            axes.plot([score["normalized_score"]], [row], "|", color="black", markersize=12)
        axes.set_yticks(range(len(entries)), [e["submission"]["name"] for e in entries])
        axes.invert_yaxis()
        axes.set_xlabel("normalized score over runs x tasks (95% CI); 0 = random, 1 = maximum")
        axes.grid(axis="x", alpha=0.3)
        return _svg(figure)


def performance_profiles(profiles: Sequence[tuple[str, np.ndarray]]) -> str:
    """One curve per entry: the fraction of episodes scoring above each threshold."""
    with _style():
        figure = _figure(7.5, max(3.4, _legend_height(len(profiles))))
        axes = figure.add_subplot()
        colors = _colors(len(profiles))
        for i, ((name, fractions), color) in enumerate(zip(profiles, colors, strict=True)):
            style = ("-", "--")[i // 20 % 2]  # past 20 entries, colours come back dashed
            xs, ys = _corners(THRESHOLDS, np.asarray(fractions))
            axes.plot(xs, ys, style, color=color, label=name, linewidth=1.6)
        axes.set_xlabel("normalized score threshold \N{GREEK SMALL LETTER TAU}")
        axes.set_ylabel("fraction of episodes > \N{GREEK SMALL LETTER TAU}")
        axes.set_ylim(-0.02, 1.02)
        axes.grid(alpha=0.3)
        if profiles:  # an empty track draws empty axes, without matplotlib's warning
            axes.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), frameon=False)
        return _svg(figure)


def _corners(xs: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points of a polyline where it changes direction: a profile is flat over most
    thresholds, and each point a flat run's middle adds is a line of SVG that draws
    nothing (matplotlib simplifies paths of 128 points or more only). The line drawn is
    the same, and so is its dash pattern, which runs along the path's length."""
    if len(ys) < 3:
        return xs, ys
    slopes = np.diff(ys) / np.diff(xs)
    keep = np.ones(len(ys), dtype=bool)
    keep[1:-1] = slopes[1:] != slopes[:-1]
    return xs[keep], ys[keep]


def per_task_scores(entries: Sequence[dict[str, Any]], task_ids: Sequence[str]) -> str:
    """Each task's normalized score per method (over its runs), with its interval."""
    with _style():
        figure = _figure(8.0, max(3.6, _legend_height(len(entries))))
        axes = figure.add_subplot()
        width = 0.8 / max(len(entries), 1)
        positions = np.arange(len(task_ids))
        for i, (entry, color) in enumerate(zip(entries, _colors(len(entries)), strict=True)):
            scores, lows, highs = [], [], []
            for task_id in task_ids:
                block = entry["tasks"].get(task_id)
                value = None if block is None else block.get("normalized_score")
                scores.append(np.nan if value is None else value)
                low, high = (np.nan, np.nan) if value is None else block["normalized_ci"]
                lows.append(value - low if value is not None else 0.0)
                highs.append(high - value if value is not None else 0.0)
            axes.bar(
                positions + (i - (len(entries) - 1) / 2) * width,
                scores,
                width,
                yerr=[lows, highs],
                color=color,
                label=entry["submission"]["name"],
                error_kw={"elinewidth": 0.8, "capsize": 0},
            )
        labels = [task_id.removeprefix("bbbench/") for task_id in task_ids]
        axes.set_xticks(positions, labels, rotation=25, ha="right")
        axes.set_ylabel("normalized score (95% CI)")
        axes.axhline(0.0, color="black", linewidth=0.6)
        axes.grid(axis="y", alpha=0.3)
        if entries:  # an empty track draws empty axes, without matplotlib's warning
            axes.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), frameon=False)
        return _svg(figure)


def score_curves(panels: Sequence[dict[str, Any]], columns: int = 3, bands: bool = True):
    """Small multiples of normalized score against a parameter: one panel per
    `{"title", "xlabel", "lines": [(label, xs, scores, lows, highs), ...]}` (and "built",
    the value the task is built with, drawn as a dotted line), each line with its 95%
    interval as a band unless `bands` is False; a line's colour is the same in every
    panel. Returns the figure (`svg_text`, `png_bytes`)."""
    labels = list(dict.fromkeys(line[0] for panel in panels for line in panel["lines"]))
    colors = dict(zip(labels, _colors(len(labels)), strict=True))
    columns = min(columns, len(panels))
    rows = -(-len(panels) // columns)
    with _style():
        figure = _figure(2.6 * columns + 1.8, max(2.3 * rows, _legend_height(len(labels))))
        grid = figure.subplots(rows, columns, squeeze=False, sharey=True)
        for axes, panel in zip(grid.flat, panels, strict=False):
            for i, (label, xs, scores, lows, highs) in enumerate(panel["lines"]):
                color = colors[label]
                if bands:
                    axes.fill_between(xs, lows, highs, color=color, alpha=0.18, linewidth=0)
                style = ("o-", "o--")[i // 20 % 2]  # past 20 lines, colours come back dashed
                axes.plot(xs, scores, style, color=color, label=label, markersize=3)
            if panel.get("built") is not None:
                axes.axvline(panel["built"], color="grey", linewidth=0.8, linestyle=":")
            axes.set_title(panel["title"])
            axes.set_xlabel(panel["xlabel"])
            axes.axhline(0.0, color="black", linewidth=0.6)
            axes.grid(alpha=0.3)
        for axes in grid[:, 0]:
            axes.set_ylabel("normalized score" + (" (95% CI)" if bands else ""))
        for axes in list(grid.flat)[len(panels) :]:
            axes.set_visible(False)
        legend = {}
        for axes in grid.flat:
            for handle, name in zip(*axes.get_legend_handles_labels(), strict=True):
                legend.setdefault(name, handle)
        figure.legend(legend.values(), legend.keys(), loc="outside right upper", frameon=False)
    return figure


def svg_text(figure) -> str:
    """The figure as SVG, the same bytes on every build."""
    with _style():
        return _svg(figure)


def png_bytes(figure) -> bytes:
    """The figure as PNG, without the metadata that would change between builds."""
    buffer = io.BytesIO()
    with _style():
        figure.savefig(buffer, format="png", dpi=150, metadata={"Software": None})
    return buffer.getvalue()

"""The leaderboard's page, index.html, and its figures: one HTML file (inline CSS and JS;
no CDN) that shows each figure from an SVG file beside it (figures/<track>-<name>.svg),
drawn from the leaderboard document and the entries' results documents (the score
distributions). The figures stay out of the page's text so that the page loads at once
and a figure's file changes only when what it draws does. Every string a submission
wrote is escaped; the cells are written as `bbbench.leaderboard.views` writes them for
the Markdown page and the terminal."""

from __future__ import annotations

import dataclasses
import html
from collections.abc import Mapping, Sequence
from typing import Any

from bbbench.leaderboard import plots
from bbbench.leaderboard.ranking import performance_profile
from bbbench.leaderboard.views import (
    HOW_TO_READ,
    LEGEND,
    TEAM_SIZES_NOTE,
    columns,
    header_kind,
    header_name,
    overall_cell,
    rank_cell,
    robustness_cell,
    run_name,
    run_task_cell,
    size_rows,
    steps_cell,
    task_cell,
    task_name,
    versus_cell,
)
from bbbench.tasks.perturbations import PERTURBATIONS

_CSS = """
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",sans-serif;margin:2em auto;max-width:80em;
padding:0 1em;color:#1b1f24}
h1{font-size:1.6em;margin-bottom:.2em}h2{margin-top:2em}p.meta{color:#57606a;margin-top:0}
div.scroll{overflow-x:auto;margin:1em 0}table.board{border-collapse:collapse;width:100%}
table.board th,table.board td{padding:.35em .6em;border-bottom:1px solid #d0d7de;text-align:right;
white-space:nowrap}
table.board th:nth-child(2),table.board td:nth-child(2),table.board th:nth-child(3),
table.board td:nth-child(3){text-align:left}
table.board th{cursor:pointer;user-select:none;background:#f6f8fa;position:sticky;top:0}
table.board th.old{color:#57606a;font-weight:normal}
table.board th[aria-sort=ascending]::after{content:" \\25B2"}
table.board th[aria-sort=descending]::after{content:" \\25BC"}
tr.entry{cursor:pointer}tr.entry:hover{background:#f6f8fa}
tr.run td{color:#57606a;font-size:.92em;border-bottom:1px dotted #d0d7de}
td small{color:#57606a}tr.details td{text-align:left;background:#fbfcfd;white-space:normal}
dl{display:grid;grid-template-columns:max-content auto;gap:.2em 1em;margin:.4em 0}
dt{font-weight:600}dd{margin:0;overflow-wrap:anywhere}
figure{margin:1.5em 0}figcaption{color:#57606a;margin-bottom:.4em}
figure img{max-width:100%;height:auto}
"""

_SCRIPT = """
document.querySelectorAll("table.board").forEach(function (table) {
  // A method is a tbody: its row, its runs' rows and its details; sorting moves it whole.
  var methods = Array.prototype.slice.call(table.tBodies);
  table.querySelectorAll("thead th").forEach(function (header, column) {
    header.addEventListener("click", function () {
      var ascending = header.getAttribute("aria-sort") !== "ascending";
      table.querySelectorAll("th").forEach(function (h) { h.removeAttribute("aria-sort"); });
      header.setAttribute("aria-sort", ascending ? "ascending" : "descending");
      var numeric = header.dataset.type === "number";
      var sorted = methods.slice().sort(function (a, b) {
        var x = a.rows[0].cells[column].dataset.value, y = b.rows[0].cells[column].dataset.value;
        var order = numeric ? parseFloat(x) - parseFloat(y) : x.localeCompare(y);
        if (numeric && isNaN(order)) { order = isNaN(parseFloat(x)) ? 1 : -1; }
        if (numeric && isNaN(parseFloat(x)) && isNaN(parseFloat(y))) { order = 0; }
        order = ascending ? order : -order;
        // ties keep the board's order
        return order || a.dataset.position - b.dataset.position;
      });
      sorted.forEach(function (method) { table.appendChild(method); });
    });
  });
  table.addEventListener("click", function (event) {
    var row = event.target.closest("tr.entry");
    if (row) {
      var details = row.parentNode.querySelector("tr.details");
      details.hidden = !details.hidden;
      row.setAttribute("aria-expanded", String(!details.hidden));
    }
  });
});
"""


def _e(text: Any) -> str:
    return html.escape(str(text), quote=True)


def _number(value: float | None) -> str:
    return "" if value is None else repr(float(value))


def _details(method: dict[str, Any], width: int) -> str:
    """A method's details: its submission, and each run's records."""
    submission = method["submission"]
    recipe = submission["recipe"]
    items = [
        ("authors", ", ".join(submission["authors"])),
        ("algorithm", submission["algorithm"]),
        ("action mode", submission["action_mode"]),
        ("tracks", ", ".join(submission["tracks"])),
        ("training steps", f"{recipe['world_steps']:,} world steps"),
        ("trained on", ", ".join(map(task_name, recipe["tasks"])) or "-"),
        ("recipe", recipe["file"]),
        ("height scan", "yes" if method["height_scan"] else "no"),
        ("licence", submission["licence"]),
    ]
    if method["unranked"]:
        items.insert(0, ("unranked", method["unranked"]))
    items += [(key, submission[key]) for key in ("date", "notes") if key in submission]
    listing = "".join(f"<dt>{_e(key)}</dt><dd>{_e(value)}</dd>" for key, value in items)
    if submission.get("url"):
        listing += f"<dt>link</dt><dd>{_link(submission['url'])}</dd>"
    for run in method["runs"]:
        record, policy = run["record"], run["policy"]
        what = (
            f"built-in '{submission['builtin']}'"
            if "builtin" in submission
            else f"policy.{policy.get('format', 'zip')}, SHA-256 {policy['sha256']}"
        )
        listing += (
            f"<dt>{_e(run_name(run))}</dt><dd>{_e(what)}; {_e(record['wall_time'])} on "
            f"{_e(record['hardware'])}; {_code(record['command'])}; "
            f"{_link(run['results'])}</dd>"
        )
    return f'<tr class="details" hidden><td colspan="{width}"><dl>{listing}</dl></td></tr>'


def _code(text: str) -> str:
    return f"<code>{_e(text)}</code>"


def _link(target: str) -> str:
    return f'<a href="{_e(target)}" rel="nofollow noopener">{_e(target)}</a>'


def _cell(value: Any, shown: str) -> str:
    """A table cell; `value` (a number, text or None) is what sorting compares."""
    key = _e(value) if isinstance(value, str) else _number(value)
    return f'<td data-value="{key}">{shown}</td>'


def _score_cell(text: str) -> str:
    """'0.373 (25%)' as the score with the success rate small beside it."""
    score, _, success = text.partition(" ")
    return _e(score) + (f" <small>{_e(success)}</small>" if success else "")


def _table(track: dict[str, Any]) -> str:
    task_ids = columns(track)
    headers = [
        ("Rank", "number", ""),
        ("Name", "text", ""),
        ("Algorithm", "text", ""),
        ("Runs", "number", ""),
        ("Training steps", "number", ""),
        ("Overall [95% CI]", "number", ""),
        ("Robustness (worst)", "number", ""),
        *((header_name(track, t), "number", header_kind(track, t)) for t in task_ids),
        ("P(> next)", "number", ""),
    ]
    head = "".join(
        f'<th data-type="{kind}"' + (f' class="{css}"' if css else "") + f">{_e(label)}</th>"
        for label, kind, css in headers
    )
    bodies = []
    for position, method in enumerate(track["methods"]):
        submission = method["submission"]
        robustness = method["robustness"]
        cells = [
            (method["rank"], _e(rank_cell(method))),
            (submission["name"], _e(submission["name"])),
            (submission["algorithm"], _e(submission["algorithm"])),
            (len(method["runs"]), str(len(method["runs"]))),
            (submission["recipe"]["world_steps"], _e(steps_cell(method))),
            (method["overall"].get("normalized_score"), _e(overall_cell(method))),
            (
                None if robustness is None else robustness["score"],
                _score_cell(robustness_cell(method)),
            ),
        ]
        for task_id in task_ids:
            block = method["tasks"].get(task_id)
            value = None if block is None else block.get("normalized_score")
            cells.append((value, _score_cell(task_cell(method, task_id))))
        versus = method["versus_next"]
        versus_value = None if versus is None else versus["probability_of_improvement"]
        cells.append((versus_value, _e(versus_cell(method))))
        row = "".join(_cell(value, shown) for value, shown in cells)
        runs = (
            "".join(_run_row(run, task_ids) for run in method["runs"])
            if len(method["runs"]) > 1
            else ""
        )
        bodies.append(
            f'<tbody data-slug="{_e(method["slug"])}" data-position="{position}">'
            f'<tr class="entry" tabindex="0" aria-expanded="false"'
            + (f' title="unranked: {_e(method["unranked"])}"' if method["unranked"] else "")
            + f">{row}</tr>{runs}{_details(method, len(cells))}</tbody>"
        )
    return (
        f'<div class="scroll"><table class="board" id="table-{_e(track["track"])}">'
        f"<thead><tr>{head}</tr></thead>{''.join(bodies)}</table></div>"
    )


def _sizes_table(track: dict[str, Any]) -> str:
    """The track's team-size table (`views.size_rows`), or nothing."""
    sized = size_rows(track)
    if sized is None:
        return ""
    (task, header), body = sized
    head = "".join(f"<th>{_e(cell)}</th>" for cell in header)
    rows = "".join(
        "<tr>" + "".join(f"<td>{_e(cell)}</td>" for cell in row) + "</tr>" for row in body
    )
    return (
        f"<h3>Team sizes on {_e(task_name(task))}</h3><p>{_e(TEAM_SIZES_NOTE)}.</p>"
        f'<table class="sizes"><thead><tr>{head}</tr></thead><tbody>{rows}</tbody></table>'
    )


def _run_row(run: dict[str, Any], task_ids: list[str]) -> str:
    """A run beneath its method: its name, its robustness, its score on each task."""
    cells = ["<td></td>", f"<td>{_e(run_name(run))}</td>", "<td></td>" * 4]  # to overall
    cells.append(f"<td>{_score_cell(robustness_cell(run))}</td>")
    cells += [f"<td>{_score_cell(run_task_cell(run, t))}</td>" for t in task_ids]
    return f'<tr class="run">{"".join(cells)}<td></td></tr>'


def robustness_panels(entries: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The board's robustness figure: a panel per axis, a line per method."""
    axes = list(dict.fromkeys(axis for e in entries for axis in e["robustness"]["axes"]))
    panels = []
    for axis in axes:
        lines = []
        for entry in entries:
            points = entry["robustness"]["axes"].get(axis)
            if points is not None:
                values, scores, lows, highs = zip(*points["points"], strict=True)
                lines.append((entry["submission"]["name"], values, scores, lows, highs))
        kind = PERTURBATIONS[axis]
        panels.append(
            {
                "title": axis,
                "xlabel": kind.unit,
                "lines": lines,
                "built": dataclasses.fields(kind)[0].default,
            }
        )
    return panels


README_FIGURE = "../docs/images/robustness.svg"  # beside the board: the robustness guide's
FIGURES = "figures"  # the page's figures, one SVG file each, beside index.html


def is_figure(name: str) -> bool:
    """Whether the board's file `name` (a path inside its folder) is a figure."""
    return name == README_FIGURE or name.startswith(f"{FIGURES}/")


def readme_robustness_figure(document: dict[str, Any]) -> str | None:
    """The robustness guide's figure (docs/guides/robustness.md): PD, LQR and the
    best-ranked PPO method of the single-bot track on every axis (a method's band: its
    runs' least and greatest score); None without them."""
    entries = next(t for t in document["tracks"] if t["track"] == "single")["methods"]
    profiled = [e for e in entries if e["robustness"] is not None]
    chosen = [e for slug in ("pd", "lqr") for e in profiled if e["slug"] == slug]
    chosen += [e for e in profiled if e["submission"]["algorithm"] == "PPO"][:1]
    if len(chosen) < 3:
        return None
    return plots.svg_text(plots.score_curves(robustness_panels(chosen), columns=4))


def page(document: dict[str, Any], results: Mapping[str, dict[str, Any]]) -> dict[str, str]:
    """index.html (the tables, sortable; an entry's metadata on click) and its figures:
    path inside the board's folder -> text."""
    files = {}
    sections = []
    for track in document["tracks"]:
        figures_html = ""
        for name, caption, svg in _figures(track, results):
            path = f"{FIGURES}/{track['track']}-{name}.svg"
            files[path] = svg + "\n"
            figures_html += (
                f'<figure class="plot" id="{_e(track["track"])}-{name}">'
                f"<figcaption>{_e(caption)}</figcaption>"
                f'<img src="{_e(path)}" alt="{_e(caption)}" loading="lazy" '
                f'width="{_size(svg, "width")}" height="{_size(svg, "height")}"></figure>'
            )
        sections.append(
            f'<section id="track-{_e(track["track"])}"><h2>{_e(track["title"].capitalize())}</h2>'
            f"{_table(track)}{_sizes_table(track)}{figures_html}</section>"
        )
    legend = " ".join(LEGEND.replace("**", "").replace("`", "").split())
    intro = " ".join(HOW_TO_READ.replace("**", "").replace("`", "").split())
    files["index.html"] = (
        "<!DOCTYPE html>\n"
        '<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>bbbench leaderboard</title><style>{_CSS}</style></head><body>"
        "<h1>bbbench leaderboard</h1>"
        f'<p class="meta">bbbench {_e(document["bbbench_version"])} (harness '
        f"{_e(document['harness_version'])}), pybullet {_e(document['pybullet_version'])}. "
        'Data: <a href="bbbench-v0.json">bbbench-v0.json</a>. Click a column to sort, '
        "an entry for its details.</p>"
        f"<p>{_e(legend)}</p>{''.join(sections)}<h2>How to read it</h2><p>{_e(intro)}</p>"
        f"<script>{_SCRIPT}</script></body></html>\n"
    )
    return files


def _figures(
    track: dict[str, Any], results: Mapping[str, dict[str, Any]]
) -> list[tuple[str, str, str]]:
    """A track's figures: (name, caption, SVG text)."""
    entries = track["methods"]
    counted = [t["task"] for t in track["tasks"] if t["overall"]]
    profiles = [
        (
            e["submission"]["name"],
            performance_profile(
                [results[run["slug"]] for run in e["runs"]], counted, plots.THRESHOLDS
            ),
        )
        for e in entries
    ]
    figures = [
        (
            "interval-estimates",
            "Overall: each method's score over runs x the track's tasks (but saturated "
            "ones), with its 95% two-level bootstrap interval.",
            plots.interval_estimates([e for e in entries if e["overall"].get("tasks")]),
        ),
        (
            "performance-profiles",
            "Score distributions: the fraction of episodes (averaged over runs and the "
            "track's tasks in its overall) whose normalized score is above each threshold.",
            plots.performance_profiles(profiles),
        ),
        (
            "per-task",
            "Per task: each method's score over its runs, with its 95% interval.",
            plots.per_task_scores(entries, columns(track)),
        ),
    ]
    profiled = [entry for entry in entries if entry["robustness"] is not None]
    if profiled:
        played = sorted({task_name(entry["robustness"]["task"]) for entry in profiled})
        figures.append(
            (
                "robustness",
                f"Robustness profiles on {' and '.join(played)}: each method's mean normalized "
                "score over its runs (20 evaluation seeds each) at each value of each "
                "perturbation's standard grid; the dotted line is the task as built.",
                plots.svg_text(
                    plots.score_curves(robustness_panels(profiled), columns=4, bands=False)
                ),
            )
        )
    return figures


def _size(svg: str, attribute: str) -> str:
    """The figure's width or height in CSS pixels, from its `<svg>` tag's points, so
    that the page keeps each figure's place before it loads."""
    tag = svg[: svg.index(">")]
    points = float(tag.split(f' {attribute}="', 1)[1].split("pt", 1)[0])
    return str(round(points * 4 / 3))

"""The leaderboard as people read it: a Markdown page (leaderboards/README.md), a terminal
table (`bbbench leaderboard show`) and one self-contained HTML file (index.html: inline
CSS, JS and SVG; no CDN). All are drawn from the leaderboard document (and, for the
score distributions, the entries' results documents); every string a submission wrote
is escaped."""

from __future__ import annotations

import dataclasses
import html
from collections.abc import Mapping, Sequence
from typing import Any

from bbbench.leaderboard import plots
from bbbench.leaderboard.board import performance_profile
from bbbench.tasks.perturbations import PERTURBATIONS

HOW_TO_READ = """\
Every entry is re-scored by CI from the files in `submissions/` (`bbbench leaderboard
check`), on every evaluation seed of every task, with the shipped harness: nothing
here is copied from a paper or a log. A score is normalized per task: 0 is the
random policy's mean return, 1 the task's maximum return. **Overall** is the IQM
(interquartile mean) of the per-episode normalized scores over the track's tasks
(the latest version of each task), with its 95% stratified-bootstrap interval.
**Rank**: entries are ordered by Overall, and neighbours share a rank unless the
95% interval of P(upper > lower), rliable's probability of improvement, lies
above 0.5. A superseded task version leaves the board; its last numbers stay in
the repository's history. Per task: normalized score of the mean return, and in
brackets the success rate (episodes with no fall). **Robustness** (not part of the
rank): the entry's profile on the track, under one fixed protocol per track: the latest
version of the track's profile task (VelocityTracking; MultiBalance on the multi-bot
track, BeamCarry on the cooperative one, LeggedVelocityTracking on the wheel-legged one)
on 20 evaluation seeds at each value of each perturbation's standard grid that applies
(payload, centre of mass, friction, motor strength, action delay, sensor noise, pushes;
a multi-bot task takes no sensor noise, BeamCarry no centre of mass and carries the
payload on its beam): the mean over the axes of each axis's mean
normalized score, and in brackets the worst case, the least normalized score at any
point (`bbbench sweep` plays any axis of it)."""


def _fixed(value: float, digits: int = 3) -> str:
    """`value` to `digits` decimals, without the sign of a value that rounds to zero."""
    text = f"{value:.{digits}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text


def _name(task_id: str) -> str:
    return task_id.removeprefix("bbbench/")


def _steps(entry: dict[str, Any]) -> str:
    steps = entry["submission"]["training"]["env_steps"]
    if steps == 0:
        return "-"
    for size, unit in ((10**9, "G"), (10**6, "M"), (10**3, "k")):
        if steps >= size:
            return f"{steps / size:.3g}{unit}"
    return str(steps)


def _overall(entry: dict[str, Any]) -> str:
    score = entry["overall"]
    if not score.get("tasks"):
        return "-"
    low, high = score["normalized_iqm_ci"]
    return f"{_fixed(score['normalized_iqm'])} [{_fixed(low)}, {_fixed(high)}]"


def _robustness(entry: dict[str, Any]) -> str:
    profile = entry["robustness"]
    if profile is None:
        return "-"
    return f"{_fixed(profile['score'])} ({_fixed(profile['worst_case'])})"


def _task_cell(entry: dict[str, Any], task_id: str) -> str:
    block = entry["tasks"].get(task_id)
    if block is None or not block.get("episodes"):
        return "-"
    value = block["normalized_score"]
    shown = "-" if value is None else _fixed(value)
    return f"{shown} ({block['success_rate']:.0%})"


def _versus(entry: dict[str, Any]) -> str:
    versus = entry["versus_next"]
    if versus is None or versus["probability_of_improvement"] is None:
        return "-"
    low, high = versus["ci"]
    return f"{versus['probability_of_improvement']:.2f} [{low:.2f}, {high:.2f}]"


def _columns(track: dict[str, Any]) -> list[str]:
    ranked = [t["task"] for t in track["tasks"] if t["ranked"]]
    return ranked + [t["task"] for t in track["tasks"] if not t["ranked"]]


def _is_ranked(track: dict[str, Any], task_id: str) -> bool:
    return any(t["task"] == task_id and t["ranked"] for t in track["tasks"])


def _header_name(track: dict[str, Any], task_id: str) -> str:
    return _name(task_id) + ("" if _is_ranked(track, task_id) else " (old)")


def rows(track: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    """The ranked table of a track as text: header and rows (Markdown and terminal)."""
    header = ["rank", "name", "algorithm", "training steps", "overall [95% CI]"]
    header += ["robustness (worst)"]
    header += [_header_name(track, task_id) for task_id in _columns(track)]
    header += ["P(> next) [95% CI]"]
    body = [
        [
            str(entry["rank"]),
            entry["submission"]["name"],
            entry["submission"]["algorithm"],
            _steps(entry),
            _overall(entry),
            _robustness(entry),
            *(_task_cell(entry, task_id) for task_id in _columns(track)),
            _versus(entry),
        ]
        for entry in track["entries"]
    ]
    return header, body


def _markdown_cell(text: str) -> str:
    return html.escape(text, quote=False).replace("|", "\\|").replace("\n", " ")


def markdown(document: dict[str, Any]) -> str:
    """leaderboards/README.md."""
    lines = [
        "# bbbench leaderboard",
        "",
        "<!-- Generated by `bbbench leaderboard build`; CI checks it. Do not edit. -->",
        "",
        f"bbbench {document['bbbench_version']} (harness {document['harness_version']}), "
        f"pybullet {document['pybullet_version']}. The data: [bbbench-v0.json](bbbench-v0.json) "
        f"and [results/](results/) (one `bbbench eval --json` document per entry); the page "
        f"with plots: [index.html](index.html).",
        "",
        HOW_TO_READ,
    ]
    for track in document["tracks"]:
        header, body = rows(track)
        lines += ["", f"## {track['title'].capitalize()}", ""]
        lines.append("| " + " | ".join(header) + " |")
        lines.append("|" + "|".join("---" if i < 3 else "---:" for i in range(len(header))) + "|")
        lines += ["| " + " | ".join(_markdown_cell(cell) for cell in row) + " |" for row in body]
        lines += ["", "Tasks (fingerprint, evaluation seeds):", ""]
        lines += [
            f"- `{task['task']}` `{task['fingerprint']}`, {task['episodes']} seeds "
            f"(SHA-256 `{task['eval_seeds_sha256'][:16]}`)"
            + ("" if task["ranked"] else "; not ranked (an older version)")
            for task in track["tasks"]
        ]
    lines += ["", "## How to submit", "", SUBMITTING]
    return "\n".join(lines) + "\n"


BASELINES_START = "<!-- baselines: generated by bbbench leaderboard build; do not edit -->"
BASELINES_END = "<!-- baselines: end -->"


def baselines_table(document: dict[str, Any]) -> str:
    """The single-bot track as a compact Markdown table (the ranked tasks only), for the
    main README's Baselines section."""
    track = next(t for t in document["tracks"] if t["track"] == "single")
    header, body = rows(track)
    keep = [i for i, name in enumerate(header) if "(old)" not in name and "next" not in name]
    lines = ["| " + " | ".join(header[i] for i in keep) + " |"]
    lines.append("|" + "|".join("---" if i < 3 else "---:" for i in range(len(keep))) + "|")
    lines += ["| " + " | ".join(_markdown_cell(row[i]) for i in keep) + " |" for row in body]
    return "\n".join(lines)


def with_baselines(readme: str, document: dict[str, Any]) -> str | None:
    """`readme` with the text between the baselines markers replaced by the table; None
    if it has no markers."""
    start, end = readme.find(BASELINES_START), readme.find(BASELINES_END)
    if start < 0 or end < start:
        return None
    head = readme[: start + len(BASELINES_START)]
    return f"{head}\n{baselines_table(document)}\n{readme[end:]}"


SUBMITTING = """\
A submission is a folder, `submissions/<slug>/`: `submission.json` (who, what, the
training budget: docs/submission-schema.json) and the policy file, a
stable-baselines3 `policy.zip` or an ONNX `policy.onnx`. bbbench reads either
without running anything in it: nothing in a zip is unpickled, and an ONNX graph
is run by bbbench's own interpreter of a few operators (no external files, no
custom operators, capped sizes), on arithmetic that gives the same bits on every
CPU.

**From stable-baselines3** (PPO, A2C, DQN, SAC, TD3, and sb3-contrib's QR-DQN,
TQC, TRPO, ARS), the zip as `model.save()` wrote it, with `--vecnormalize
vecnormalize.pkl` if it trained inside VecNormalize; or as ONNX, `bbbench export
policy.zip --out policy.onnx` (it plays the zip's episodes byte for byte).

**From any torch policy** (CleanRL, skrl, rsl_rl: the module that maps an
observation to action scores or to the action), with the normalizer it trained
behind:

```python
from bbbench.policies import export_onnx

export_onnx(
    agent.actor,
    "bbbench/FlatBalance-v1",
    "policy.onnx",
    mean=obs_rms.mean,
    std=np.sqrt(obs_rms.var + 1e-8),
    clip=10.0,
    algorithm="PPO (CleanRL)",
    training_steps=1_000_000,
)
```

**From RLlib, TorchRL or Isaac Lab exports** (`Policy.export_model(dir, onnx=17)`,
`torch.onnx.export`, `export_policy_as_onnx`): the graph's input must be the raw
bbbench observation, its output the scores or the action. Give the file its
contract, and keep the one output that acts:

```bash
bbbench export model.onnx --out policy.onnx --output output \\
    --observation 5 --action-space "Discrete(9)" --algorithm PPO --training-steps 1000000
```

Then, in a fork of the repository:

```bash
bbbench eval policy.onnx                 # what it scores, on the tasks it fits
bbbench leaderboard add policy.onnx --slug my-ppo --name "My PPO" --algorithm PPO \\
    --author "A. Person" --env-steps 1000000 --wall-time "40 min" \\
    --hardware "2 CPU cores" --seeds 0 --command "python train.py --seed 0" --licence MIT
```

`leaderboard add` checks the file with the same safe reader as `bbbench eval`,
writes `submissions/my-ppo/`, scores it on every evaluation seed and rebuilds
these pages. Commit the folder and the regenerated files, and open a pull
request: the leaderboard workflow (.github/workflows/leaderboard.yml) re-scores
new and changed entries in full and fails if any number differs, and uploads
the rebuilt board; once merged, the page is published."""


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
td small{color:#57606a}tr.details td{text-align:left;background:#fbfcfd;white-space:normal}
dl{display:grid;grid-template-columns:max-content auto;gap:.2em 1em;margin:.4em 0}
dt{font-weight:600}dd{margin:0;overflow-wrap:anywhere}
figure{margin:1.5em 0}figcaption{color:#57606a;margin-bottom:.4em}
figure svg{max-width:100%;height:auto}
"""

_SCRIPT = """
document.querySelectorAll("table.board").forEach(function (table) {
  var body = table.tBodies[0];
  function pairs() {
    return Array.prototype.map.call(body.querySelectorAll("tr.entry"), function (row) {
      return [row, row.nextElementSibling];
    });
  }
  table.querySelectorAll("th").forEach(function (header, column) {
    header.addEventListener("click", function () {
      var ascending = header.getAttribute("aria-sort") !== "ascending";
      table.querySelectorAll("th").forEach(function (h) { h.removeAttribute("aria-sort"); });
      header.setAttribute("aria-sort", ascending ? "ascending" : "descending");
      var numeric = header.dataset.type === "number";
      var sorted = pairs().sort(function (a, b) {
        var x = a[0].cells[column].dataset.value, y = b[0].cells[column].dataset.value;
        var order = numeric ? parseFloat(x) - parseFloat(y) : x.localeCompare(y);
        if (numeric && isNaN(order)) { order = isNaN(parseFloat(x)) ? 1 : -1; }
        if (numeric && isNaN(parseFloat(x)) && isNaN(parseFloat(y))) { order = 0; }
        order = ascending ? order : -order;
        // ties keep the board's order
        return order || a[0].dataset.position - b[0].dataset.position;
      });
      sorted.forEach(function (pair) { body.appendChild(pair[0]); body.appendChild(pair[1]); });
    });
  });
  body.addEventListener("click", function (event) {
    var row = event.target.closest("tr.entry");
    if (row) {
      row.nextElementSibling.hidden = !row.nextElementSibling.hidden;
      row.setAttribute("aria-expanded", String(!row.nextElementSibling.hidden));
    }
  });
});
"""


def _e(text: Any) -> str:
    return html.escape(str(text), quote=True)


def _number(value: float | None) -> str:
    return "" if value is None else repr(float(value))


def _details(entry: dict[str, Any], width: int) -> str:
    submission = entry["submission"]
    policy = entry["policy"]
    items = [
        ("authors", ", ".join(submission["authors"])),
        ("algorithm", submission["algorithm"]),
        ("action mode", submission["action_mode"]),
        (
            "policy",
            f"built-in '{submission['builtin']}'"
            if "builtin" in submission
            else f"policy.{policy.get('format', 'zip')}, SHA-256 {policy['sha256']}",
        ),
        ("height scan", "yes" if entry["height_scan"] else "no"),
        ("training steps", f"{submission['training']['env_steps']:,}"),
        ("wall time", submission["training"]["wall_time"]),
        ("hardware", submission["training"]["hardware"]),
        ("training seeds", ", ".join(map(str, submission["training_seeds"])) or "-"),
        ("command", submission["command"]),
        ("licence", submission["licence"]),
    ]
    items += [(key, submission[key]) for key in ("date", "notes") if key in submission]
    listing = "".join(
        f"<dt>{_e(key)}</dt><dd>{_code(value) if key == 'command' else _e(value)}</dd>"
        for key, value in items
    )
    if submission.get("url"):
        listing += f"<dt>link</dt><dd>{_link(submission['url'])}</dd>"
    listing += f"<dt>results</dt><dd>{_link(entry['results'])}</dd>"
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
    columns = _columns(track)
    headers = [
        ("Rank", "number", ""),
        ("Name", "text", ""),
        ("Algorithm", "text", ""),
        ("Training steps", "number", ""),
        ("Overall [95% CI]", "number", ""),
        ("Robustness (worst)", "number", ""),
        *(
            (_header_name(track, t), "number", "" if _is_ranked(track, t) else "old")
            for t in columns
        ),
        ("P(> next)", "number", ""),
    ]
    head = "".join(
        f'<th data-type="{kind}"' + (f' class="{css}"' if css else "") + f">{_e(label)}</th>"
        for label, kind, css in headers
    )
    body = []
    for position, entry in enumerate(track["entries"]):
        submission = entry["submission"]
        score = entry["overall"]
        cells = [
            (entry["rank"], str(entry["rank"])),
            (submission["name"], _e(submission["name"])),
            (submission["algorithm"], _e(submission["algorithm"])),
            (submission["training"]["env_steps"], _e(_steps(entry))),
            (score.get("normalized_iqm"), _e(_overall(entry))),
            (
                None if entry["robustness"] is None else entry["robustness"]["score"],
                _score_cell(_robustness(entry)),
            ),
        ]
        for task_id in columns:
            block = entry["tasks"].get(task_id)
            value = None if block is None else block.get("normalized_score")
            cells.append((value, _score_cell(_task_cell(entry, task_id))))
        versus = entry["versus_next"]
        versus_value = None if versus is None else versus["probability_of_improvement"]
        cells.append((versus_value, _e(_versus(entry))))
        row = "".join(_cell(value, shown) for value, shown in cells)
        body.append(
            f'<tr class="entry" data-slug="{_e(entry["slug"])}" data-position="{position}" '
            f'tabindex="0" aria-expanded="false">'
            f"{row}</tr>" + _details(entry, len(cells))
        )
    return (
        f'<div class="scroll"><table class="board" id="table-{_e(track["track"])}">'
        f"<thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table></div>"
    )


def robustness_panels(entries: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The board's robustness figure: a panel per axis, a line per entry."""
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


README_FIGURE = "../docs/images/robustness.svg"  # beside the board: the project's README's


def readme_robustness_figure(document: dict[str, Any]) -> str | None:
    """The main README's robustness figure: PD, LQR and the best-ranked PPO entry of the
    single-bot track on every axis, with 95% intervals; None without them."""
    entries = next(t for t in document["tracks"] if t["track"] == "single")["entries"]
    profiled = [e for e in entries if e["robustness"] is not None]
    chosen = [e for slug in ("pd", "lqr") for e in profiled if e["slug"] == slug]
    chosen += [e for e in profiled if e["submission"]["algorithm"] == "PPO"][:1]
    if len(chosen) < 3:
        return None
    return plots.svg_text(plots.score_curves(robustness_panels(chosen), columns=4))


def page(document: dict[str, Any], results: Mapping[str, dict[str, Any]]) -> str:
    """index.html: the tables, sortable; an entry's metadata on click; the figures."""
    sections = []
    for track in document["tracks"]:
        entries = track["entries"]
        ranked = [t["task"] for t in track["tasks"] if t["ranked"]]
        profiles = [
            (
                e["submission"]["name"],
                performance_profile(results[e["slug"]], ranked, plots.THRESHOLDS),
            )
            for e in entries
        ]
        figures = [
            (
                "interval-estimates",
                "Overall: IQM of normalized scores over the ranked tasks, with 95% intervals.",
                plots.interval_estimates(entries),
            ),
            (
                "performance-profiles",
                "Score distributions: the fraction of episodes (averaged over the ranked tasks) "
                "whose normalized score is above each threshold.",
                plots.performance_profiles(profiles),
            ),
            (
                "per-task",
                "Per task: the normalized score of the mean return, with its 95% interval.",
                plots.per_task_scores(entries, _columns(track)),
            ),
        ]
        profiled = [entry for entry in entries if entry["robustness"] is not None]
        if profiled:
            played = sorted({_name(entry["robustness"]["task"]) for entry in profiled})
            figures.append(
                (
                    "robustness",
                    f"Robustness profiles on {' and '.join(played)} (each entry on the first it "
                    "fits): the normalized score (20 evaluation seeds) at each value of each "
                    "perturbation's standard grid; the dotted line is the task as built.",
                    plots.svg_text(
                        plots.score_curves(robustness_panels(profiled), columns=4, bands=False)
                    ),
                )
            )
        figures_html = "".join(
            f'<figure class="plot" id="{track["track"]}-{name}">'
            f"<figcaption>{_e(caption)}</figcaption>{svg}</figure>"
            for name, caption, svg in figures
        )
        sections.append(
            f'<section id="track-{_e(track["track"])}"><h2>{_e(track["title"].capitalize())}</h2>'
            f"{_table(track)}{figures_html}</section>"
        )
    intro = " ".join(HOW_TO_READ.replace("**", "").replace("`", "").split())
    return (
        "<!DOCTYPE html>\n"
        '<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>bbbench leaderboard</title><style>{_CSS}</style></head><body>"
        "<h1>bbbench leaderboard</h1>"
        f'<p class="meta">bbbench {_e(document["bbbench_version"])} (harness '
        f"{_e(document['harness_version'])}), pybullet {_e(document['pybullet_version'])}. "
        'Data: <a href="bbbench-v0.json">bbbench-v0.json</a>. Click a column to sort, '
        "an entry for its details.</p>"
        f"<p>{_e(intro)}</p>{''.join(sections)}<script>{_SCRIPT}</script></body></html>\n"
    )

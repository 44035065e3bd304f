"""The leaderboard as people read it: a Markdown page (leaderboards/README.md) and a
terminal table (`bbbench leaderboard show`), with the cells both share with the HTML
page (`bbbench.leaderboard.page`). All are drawn from the leaderboard document."""

from __future__ import annotations

import html
from typing import Any

LEGEND = """\
Each row is a **method**: a recipe and its runs (training seeds), the runs listed
beneath it. A score is normalized per task (0: random play, 1: the task's maximum),
each run's the mean over every evaluation episode, falls included. **Rank** counts
the ranked methods that beat it (P(other > it) above 0.5 with 95% confidence), so
ranks do not chain; a method that plays only some of a track's tasks, or a learned
one with fewer than 3 runs, is listed unranked."""

HOW_TO_READ = """\
Every number is computed from the files in `submissions/` by the shipped harness, on
every evaluation seed of every task: nothing here is copied from a paper or a log. CI
(`bbbench leaderboard check`) recomputes every number from the episode records, re-scores
in full every new or changed run, and replays 1,000 recorded episodes of the others,
drawn afresh at every run (`--full` replays them all). A method is its runs, one policy
per training seed. A run's score on a task is its normalized mean return over the task's
evaluation episodes (0: the random policy's mean return, 1: the task's maximum). A
method's score on a task, and its **Overall** over the track's tasks (the latest version
of each, but saturated ones), is the mean over runs x tasks (their IQM from 5 runs on),
with a 95% two-level bootstrap interval: runs drawn per task, then each drawn run's
episodes, so it holds both seed-to-seed variation and episode noise. **P(> next)** is
the probability that a run of the method scores above a run of the next ranked one on a
task, with its interval from the same bootstrap. **Rank** is 1 plus the number of ranked
methods whose P(other > it) has its interval above 0.5. A track ranks the methods whose
submission names it and that play every one of its tasks; a learned method needs 3 runs,
a controller is one. A task on which the classical controller and most methods score
0.95 or more is saturated: it stays as a check and leaves the overall. Training steps are
world steps (a multi-bot world step moves every bot once). Per task: the method's score,
and in brackets its runs' success rate (episodes with no fall). **Robustness** (not part
of the rank): the mean of its runs' profiles on the track (20 evaluation seeds at each
value of each perturbation's standard grid that applies, on the track's profile task),
and in brackets the worst case of any run (`bbbench sweep` plays any axis of it)."""


def fixed(value: float, digits: int = 3) -> str:
    """`value` to `digits` decimals, without the sign of a value that rounds to zero."""
    text = f"{value:.{digits}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text


def task_name(task_id: str) -> str:
    return task_id.removeprefix("bbbench/")


def steps_cell(method: dict[str, Any]) -> str:
    steps = method["submission"]["recipe"]["world_steps"]
    if steps == 0:
        return "-"
    for size, unit in ((10**9, "G"), (10**6, "M"), (10**3, "k")):
        if steps >= size:
            return f"{steps / size:.3g}{unit}"
    return str(steps)


def rank_cell(method: dict[str, Any]) -> str:
    return "-" if method["rank"] is None else str(method["rank"])


def overall_cell(entry: dict[str, Any]) -> str:
    score = entry["overall"]
    if not score.get("tasks"):
        return "-"
    low, high = score["normalized_ci"]
    return f"{fixed(score['normalized_score'])} [{fixed(low)}, {fixed(high)}]"


def robustness_cell(entry: dict[str, Any]) -> str:
    profile = entry["robustness"]
    if profile is None:
        return "-"
    return f"{fixed(profile['score'])} ({fixed(profile['worst_case'])})"


def task_cell(method: dict[str, Any], task_id: str) -> str:
    """A method's score on a task (over its runs), and its runs' success rate."""
    block = method["tasks"].get(task_id)
    if block is None:
        return "-"
    value = block.get("normalized_score")
    shown = "-" if value is None else fixed(value)
    return f"{shown} ({block['success_rate']:.0%})"


def run_task_cell(run: dict[str, Any], task_id: str) -> str:
    """A run's score on a task: its normalized mean return, and its success rate."""
    block = run["tasks"].get(task_id)
    if block is None or not block.get("episodes"):
        return "-"
    value = block["normalized_score"]
    shown = "-" if value is None else fixed(value)
    return f"{shown} ({block['success_rate']:.0%})"


def versus_cell(entry: dict[str, Any]) -> str:
    versus = entry["versus_next"]
    if versus is None or versus["probability_of_improvement"] is None:
        return "-"
    low, high = versus["ci"]
    return f"{versus['probability_of_improvement']:.2f} [{low:.2f}, {high:.2f}]"


def run_name(run: dict[str, Any]) -> str:
    seed = run["training_seed"]
    return "one run" if seed is None else f"seed {seed}"


def columns(track: dict[str, Any]) -> list[str]:
    """The track's tasks: those of its overall, then the saturated, then older versions."""
    tasks = track["tasks"]
    return (
        [t["task"] for t in tasks if t["overall"]]
        + [t["task"] for t in tasks if t["ranked"] and not t["overall"]]
        + [t["task"] for t in tasks if not t["ranked"]]
    )


def header_name(track: dict[str, Any], task_id: str) -> str:
    task = next(t for t in track["tasks"] if t["task"] == task_id)
    note = "" if task["overall"] else " (saturated)" if task["saturated"] else " (old)"
    return task_name(task_id) + note


def header_kind(track: dict[str, Any], task_id: str) -> str:
    """'' for a task of the overall, else 'old' (shown, not counted)."""
    return "" if next(t for t in track["tasks"] if t["task"] == task_id)["overall"] else "old"


def rows(track: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    """The table of a track as text (Markdown and terminal): header, and a row per method
    with a row per run beneath it."""
    header = ["rank", "name", "algorithm", "runs", "training steps", "overall [95% CI]"]
    header += ["robustness (worst)"]
    header += [header_name(track, task_id) for task_id in columns(track)]
    header += ["P(> next) [95% CI]"]
    body = []
    for method in track["methods"]:
        body.append(
            [
                rank_cell(method),
                method["submission"]["name"],
                method["submission"]["algorithm"],
                str(len(method["runs"])),
                steps_cell(method),
                overall_cell(method),
                robustness_cell(method),
                *(task_cell(method, task_id) for task_id in columns(track)),
                versus_cell(method),
            ]
        )
        if len(method["runs"]) > 1:
            body += [
                ["", f"- {run_name(run)}", "", "", "", "", robustness_cell(run)]
                + [run_task_cell(run, task_id) for task_id in columns(track)]
                + [""]
                for run in method["runs"]
            ]
    return header, body


TEAM_SIZES_NOTE = (
    "normalized score with that many bots, 20 evaluation seeds each, the mean of the "
    "method's runs; * the size it trained with; not part of the rank"
)


def size_rows(track: dict[str, Any]) -> tuple[tuple[str, list[str]], list[list[str]]] | None:
    """The track's team-size table (its profile task, then a row per profiled method: its
    name and its score at each size, the training size starred); None if no method has
    one."""
    sized = [m for m in track["methods"] if m.get("team_sizes") is not None]
    if not sized:
        return None
    sizes = [int(point[0]) for point in sized[0]["team_sizes"]["points"]]
    header = ["name", *(f"{size} bots" for size in sizes)]
    body = []
    for method in sized:
        profile = method["team_sizes"]
        body.append(
            [method["submission"]["name"]]
            + [
                fixed(point[1]) + ("*" if point[0] == profile["trained_with"] else "")
                for point in profile["points"]
            ]
        )
    return (sized[0]["team_sizes"]["task"], header), body


def unranked_notes(track: dict[str, Any]) -> list[str]:
    """Why each unranked method is: one line each."""
    return [
        f"{method['submission']['name']}: {method['unranked']}"
        for method in track["methods"]
        if method["unranked"]
    ]


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
        LEGEND,
    ]
    for track in document["tracks"]:
        header, body = rows(track)
        lines += ["", f"## {track['title'].capitalize()}", ""]
        lines.append("| " + " | ".join(header) + " |")
        lines.append("|" + "|".join("---" if i < 3 else "---:" for i in range(len(header))) + "|")
        lines += ["| " + " | ".join(_markdown_cell(cell) for cell in row) + " |" for row in body]
        notes = unranked_notes(track)
        if notes:
            lines += ["", "Unranked:", ""] + [f"- {_markdown_cell(note)}" for note in notes]
        sized = size_rows(track)
        if sized is not None:
            (task, header), body = sized
            lines += ["", f"Team sizes on {task_name(task)} ({TEAM_SIZES_NOTE}):", ""]
            lines.append("| " + " | ".join(header) + " |")
            lines.append("|---|" + "|".join("---:" for _ in header[1:]) + "|")
            lines += ["| " + " | ".join(_markdown_cell(c) for c in row) + " |" for row in body]
        lines += ["", "Tasks (fingerprint, evaluation seeds):", ""]
        lines += [f"- {task_line(task)}" for task in track["tasks"]]
    lines += ["", "## How to read it", "", HOW_TO_READ]
    lines += ["", "## How to submit", "", SUBMITTING]
    return "\n".join(lines) + "\n"


def task_line(task: dict[str, Any]) -> str:
    note = (
        ""
        if task["overall"]
        else "; saturated: shown, not in the overall"
        if task["saturated"]
        else "; not ranked (an older version)"
    )
    return (
        f"`{task['task']}` `{task['fingerprint']}`, {task['episodes']} seeds "
        f"(SHA-256 `{task['eval_seeds_sha256'][:16]}`){note}"
    )


BASELINES_START = "<!-- baselines: generated by bbbench leaderboard build; do not edit -->"
BASELINES_END = "<!-- baselines: end -->"


def baselines_table(document: dict[str, Any]) -> str:
    """The single-bot track as a compact Markdown table (the ranked tasks only), for the
    main README's Baselines section."""
    track = next(t for t in document["tracks"] if t["track"] == "single")
    header, body = rows(track)
    keep = [i for i, name in enumerate(header) if "(old)" not in name and "next" not in name]
    methods = [row for row in body if not row[1].startswith("- ")]  # runs: on the board
    lines = ["| " + " | ".join(header[i] for i in keep) + " |"]
    lines.append("|" + "|".join("---" if i < 3 else "---:" for i in range(len(keep))) + "|")
    lines += ["| " + " | ".join(_markdown_cell(row[i]) for i in keep) + " |" for row in methods]
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
A submission is a method, a folder `submissions/<method>/`: `submission.json` (who, the
recipe, its budget in world steps, its tracks: docs/submission-schema.json) and a folder
per run, `runs/s<seed>/`, with the run's `run.json` (its training seed, command, wall
time: docs/run-schema.json) and its policy file, a stable-baselines3 `policy.zip` or an
ONNX `policy.onnx`. A learned method ranks from 3 runs. bbbench reads either
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
bbbench leaderboard add policy.onnx --slug my-ppo --seed 0 --name "My PPO" \\
    --algorithm PPO --author "A. Person" --track single --licence MIT \\
    --world-steps 1000000 --trained-on bbbench/Bumps-v2 --recipe "ppo.yml" \\
    --wall-time "40 min" --hardware "2 CPU cores" --command "python train.py --seed 0"
```

and each further run with its own `--seed`, records and policy (the method's fields
may be left out). `leaderboard add` checks the file with the same safe reader as
`bbbench eval`, and the run's recipe against its method's, writes
`submissions/my-ppo/runs/s0/`, scores it on every evaluation seed and rebuilds these
pages. Commit the folder and the regenerated files, and open a pull
request: the leaderboard workflow (.github/workflows/leaderboard.yml) re-scores
new and changed runs in full and fails if any number differs, and uploads
the rebuilt board; once merged, the page is published."""

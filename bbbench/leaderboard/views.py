"""The leaderboard as people read it: a Markdown page (leaderboards/README.md) and a
terminal table (`bbbench leaderboard show`), with the cells both share with the HTML
page (`bbbench.leaderboard.page`). All are drawn from the leaderboard document."""

from __future__ import annotations

import html
from typing import Any

HOW_TO_READ = """\
Every number is computed from the files in `submissions/` by the shipped harness, on
every evaluation seed of every task: nothing here is copied from a paper or a log. CI
(`bbbench leaderboard check`) recomputes every number from the episode records, re-scores
in full every new or changed entry, and replays 1,000 recorded episodes of the others,
drawn afresh at every run (`--full` replays them all). A score is normalized per task: 0 is the
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


def fixed(value: float, digits: int = 3) -> str:
    """`value` to `digits` decimals, without the sign of a value that rounds to zero."""
    text = f"{value:.{digits}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text


def task_name(task_id: str) -> str:
    return task_id.removeprefix("bbbench/")


def steps_cell(entry: dict[str, Any]) -> str:
    steps = entry["submission"]["training"]["env_steps"]
    if steps == 0:
        return "-"
    for size, unit in ((10**9, "G"), (10**6, "M"), (10**3, "k")):
        if steps >= size:
            return f"{steps / size:.3g}{unit}"
    return str(steps)


def overall_cell(entry: dict[str, Any]) -> str:
    score = entry["overall"]
    if not score.get("tasks"):
        return "-"
    low, high = score["normalized_iqm_ci"]
    return f"{fixed(score['normalized_iqm'])} [{fixed(low)}, {fixed(high)}]"


def robustness_cell(entry: dict[str, Any]) -> str:
    profile = entry["robustness"]
    if profile is None:
        return "-"
    return f"{fixed(profile['score'])} ({fixed(profile['worst_case'])})"


def task_cell(entry: dict[str, Any], task_id: str) -> str:
    block = entry["tasks"].get(task_id)
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


def columns(track: dict[str, Any]) -> list[str]:
    ranked = [t["task"] for t in track["tasks"] if t["ranked"]]
    return ranked + [t["task"] for t in track["tasks"] if not t["ranked"]]


def is_ranked(track: dict[str, Any], task_id: str) -> bool:
    return any(t["task"] == task_id and t["ranked"] for t in track["tasks"])


def header_name(track: dict[str, Any], task_id: str) -> str:
    return task_name(task_id) + ("" if is_ranked(track, task_id) else " (old)")


def rows(track: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    """The ranked table of a track as text: header and rows (Markdown and terminal)."""
    header = ["rank", "name", "algorithm", "training steps", "overall [95% CI]"]
    header += ["robustness (worst)"]
    header += [header_name(track, task_id) for task_id in columns(track)]
    header += ["P(> next) [95% CI]"]
    body = [
        [
            str(entry["rank"]),
            entry["submission"]["name"],
            entry["submission"]["algorithm"],
            steps_cell(entry),
            overall_cell(entry),
            robustness_cell(entry),
            *(task_cell(entry, task_id) for task_id in columns(track)),
            versus_cell(entry),
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

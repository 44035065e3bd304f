"""Leaderboards: methods in the repository, each its runs (one policy per training seed),
scored by the shipped harness, ranked over runs with intervals, and checked by CI
(`bbbench leaderboard build | check | add | show`).

A leaderboard folder (`leaderboards/` in the repository) holds:

    submissions/<method>/submission.json      the method (docs/submission-schema.json)
    submissions/<method>/runs/<run>/run.json  a run's records (docs/run-schema.json)
    submissions/<method>/runs/<run>/policy.zip  its policy (or policy.onnx); a method of
                                         one run may hold it in its own folder, or name
                                         a built-in
    results/<run>.json                   a run's `bbbench eval --json` document
    results/<run>.<track>.profile.json   its robustness profile on each track its method
                                         is ranked on (`bbbench.evaluation.profile`)
    bbbench-v0.json                      the ranked board (docs/leaderboard-schema.json)
    README.md, index.html                the board as people read it
    figures/<track>-<name>.svg           the page's figures

Everything but `submissions/` is generated, with the same bytes on every build
(no dates, fixed bootstrap seeds, deterministic SVG), so `check` can compute it
again from the episode records and compare, re-score what changed, and replay a
random sample of the rest (`check(full=True)`: everything).

    from bbbench.leaderboard import build, check
    build("leaderboards")
    check("leaderboards").problems  # [] when every checked-in number is what it should be
"""

from bbbench.leaderboard.board import Board, BuildError
from bbbench.leaderboard.checking import SPOT_BUDGET, Checked, check
from bbbench.leaderboard.generation import DEFAULT_BOARD, DOCUMENT, Built, build, generate, write
from bbbench.leaderboard.submissions import MAX_POLICY_BYTES, SubmissionError
from bbbench.leaderboard.submit import add

__all__ = [
    "DEFAULT_BOARD",
    "DOCUMENT",
    "MAX_POLICY_BYTES",
    "SPOT_BUDGET",
    "Board",
    "BuildError",
    "Built",
    "Checked",
    "SubmissionError",
    "add",
    "build",
    "check",
    "generate",
    "write",
]

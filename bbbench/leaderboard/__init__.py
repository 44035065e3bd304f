"""Leaderboards: submissions in the repository, scored by the shipped harness, ranked with
intervals, and checked by CI (`bbbench leaderboard build | check | add | show`).

A leaderboard folder (`leaderboards/` in the repository) holds:

    submissions/<slug>/submission.json   metadata (docs/submission-schema.json)
    submissions/<slug>/policy.zip        the policy, unless it names a built-in
    results/<slug>.json                  its `bbbench eval --json` document
    bbbench-v0.json                      the ranked board (docs/leaderboard-schema.json)
    README.md, index.html                the board as people read it

Everything but `submissions/` is generated, with the same bytes on every build
(no dates, fixed bootstrap seeds, deterministic SVG), so `check` can rebuild
from scratch and compare.

    from bbbench.leaderboard import build, check
    build("leaderboards")
    check("leaderboards").problems  # [] when every checked-in number is re-scored exactly
"""

from bbbench.leaderboard.board import Board, BuildError
from bbbench.leaderboard.checking import Checked, check
from bbbench.leaderboard.generation import DEFAULT_BOARD, DOCUMENT, Built, build, generate, write
from bbbench.leaderboard.submissions import MAX_POLICY_BYTES, SubmissionError
from bbbench.leaderboard.submit import add

__all__ = [
    "DEFAULT_BOARD",
    "DOCUMENT",
    "MAX_POLICY_BYTES",
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

"""Leaderboard benchmark: `bbbench leaderboard build` against `bbbench eval` on the same
episodes, and the time of `bbbench leaderboard check`.

    python benchmarks/bench_leaderboard.py [--root leaderboards] [--rounds 2]

1. build: `bbbench leaderboard build --no-cache` of the board's submissions (a copy of
   `submissions/` in a temporary folder), timed from start to exit: every entry on
   every eval seed of every task it fits, statistics, JSON, Markdown, the page.
2. eval: for each entry, the command a user would run to score it alone, `bbbench
   eval POLICY --json OUT` (every task it fits, every eval seed), timed from start to
   exit; summed over the entries. The bench checks that each writes the very
   results document the build wrote.
3. check: `bbbench leaderboard check --full` on the copy (a rebuild from scratch,
   compared); `benchmarks/bench_check.py` times the default check.

Since issue 27 the build also plays each entry's robustness profile, which `bbbench
eval` does not: the throughput ratio is build's episodes per second over eval's (the
episodes each played are printed). The runs alternate, round by round, and each ratio
is computed within its round (the machine is shared and noisy).
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bbbench.evaluation.results import read

BBBENCH = [sys.executable, "-m", "bbbench"]


def timed(argv: list[str]) -> float:
    began = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - began


def policy_argument(folder: Path) -> str:
    metadata = json.loads((folder / "submission.json").read_text())
    return metadata.get("builtin") or str(folder / "policy.zip")


def episodes(results: Path) -> dict[str, int]:
    """The episodes `bbbench eval` plays for the entries ("eval"), and the build with their
    robustness profiles ("all")."""
    counts = {"eval": 0, "all": 0}
    for path in results.glob("*.json"):
        document = read(path)
        if path.name.endswith(".profile.json"):
            counts["all"] += sum(len(p["episodes"]) for a in document["axes"] for p in a["points"])
        else:
            played = sum(len(block["episodes"]) for block in document["tasks"])
            counts["eval"] += played
            counts["all"] += played
    return counts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", default="leaderboards", type=Path)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench-leaderboard-"))
    board = work / "leaderboards"
    shutil.copytree(args.root / "submissions", board / "submissions")
    folders = sorted(p for p in (board / "submissions").iterdir() if p.is_dir())
    print(f"{len(folders)} entries: {', '.join(p.name for p in folders)}")
    print(
        "| round | build (s, episodes) | eval, summed over entries (s, episodes) "
        "| **build / eval throughput** |"
    )
    print("|---|---|---|---|")
    for round_ in range(1, args.rounds + 1):
        build = timed([*BBBENCH, "leaderboard", "build", "--no-cache", "--root", str(board)])
        evals = 0.0
        for folder in folders:
            out = work / f"{folder.name}.json"
            evals += timed([*BBBENCH, "eval", policy_argument(folder), "--json", str(out)])
            written = (board / "results" / f"{folder.name}.json").read_bytes()
            if out.read_bytes() != written:
                raise SystemExit(f"{folder.name}: eval and build wrote different results")
        played = episodes(board / "results")
        ratio = (played["all"] / build) / (played["eval"] / evals)
        print(
            f"| {round_} | {build:.1f}, {played['all']} | {evals:.1f}, {played['eval']} "
            f"| **{ratio:.3f}** |",
            flush=True,
        )
    check = timed([*BBBENCH, "leaderboard", "check", "--full", "--root", str(board)])
    print(f"\ncheck of the same board: {check:.1f} s")
    shutil.rmtree(work)


if __name__ == "__main__":
    main()

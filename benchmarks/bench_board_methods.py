"""The board of methods against the board of entries it replaced (issue 65): `bbbench
leaderboard build` from the stored records, today's code on today's board against the
code and board of `--before`, and the default `bbbench leaderboard check` on today's.

    python benchmarks/bench_board_methods.py [--before b5b17e9] [--rounds 2]

Each board is a copy in a temporary folder, with its project's README.md and
docs/baselines.md beside it (the files a build also writes). The old code runs from a
git worktree of `--before` (on PYTHONPATH, with `python -S`: an editable install's finder
would take this checkout's), the new from this checkout. Both
builds play nothing (every record is stored): what is timed is reading, the statistics
(today: a two-level bootstrap per method and task, and P(X > Y) for every pair of ranked
methods of a track) and writing. The runs alternate, round by round, and each ratio is
computed within its round (the machine is shared and noisy).
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def copy_board(source: Path, target: Path) -> Path:
    """`source`'s leaderboards/, README.md and docs/baselines.md under `target`."""
    shutil.copytree(source / "leaderboards", target / "leaderboards")
    (target / "docs").mkdir(parents=True)
    shutil.copyfile(source / "README.md", target / "README.md")
    shutil.copyfile(source / "docs" / "baselines.md", target / "docs" / "baselines.md")
    return target / "leaderboards"


def timed(argv: list[str], code: Path | None = None) -> float:
    env = dict(os.environ)
    if code is not None:  # without site's .pth files, where bbbench's editable finder is
        env["PYTHONPATH"] = os.pathsep.join([str(code), sysconfig.get_paths()["purelib"]])
        argv = [argv[0], "-S", *argv[1:]]
    began = time.perf_counter()
    # From the worktree (or its parent): `-m` puts the working folder first on the path.
    where = code if code is not None else ROOT
    done = subprocess.run(argv, env=env, cwd=where, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed:\n{done.stdout}{done.stderr}")
    return time.perf_counter() - began


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", default="b5b17e9", help="the commit of the old board")
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    bbbench = [sys.executable, "-m", "bbbench", "leaderboard"]
    with tempfile.TemporaryDirectory() as scratch:
        scratch = Path(scratch)
        worktree = scratch / "before"
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "add", "-q", "--detach", str(worktree),
             args.before],
            check=True,
        )  # fmt: skip
        try:
            old = copy_board(worktree, scratch / "old")
            new = copy_board(ROOT, scratch / "new")
            for round_ in range(1, args.rounds + 1):
                before = timed([*bbbench, "build", "--root", str(old)], code=worktree)
                after = timed([*bbbench, "build", "--root", str(new)])
                print(
                    f"round {round_}: build {after:.1f} s, before ({args.before}) "
                    f"{before:.1f} s: {after / before:.2f}x",
                    flush=True,
                )
            seconds = timed([*bbbench, "check", "--root", str(new)])
            print(f"check (default) on today's board: {seconds:.0f} s", flush=True)
        finally:
            subprocess.run(
                ["git", "-C", str(ROOT), "worktree", "remove", "--force", str(worktree)],
                check=True,
            )


if __name__ == "__main__":
    main()

"""How long `bbbench leaderboard check` takes on a board of 100 methods, made from the real ones.

    python benchmarks/bench_check.py [--entries 100] [--root /tmp/bbbench-synthetic] [--full]

Copies the repository board's methods, their runs' results and their profiles under new
slugs until the board has `--entries` methods (copies of one policy score the same, so
the copies' records are what a re-score gives; the board refuses one policy twice, so
the commands run here with that one check lifted), rebuilds the board from those
records, and times, each as a whole `bbbench leaderboard` command:

- `build` from the stored records (nothing played);
- the default `check`: every number recomputed, a spot-check of the rest;
- adding one entry (a copy of a submission with no results: `build` scores it in full
  and its profile) and then the default `check` of the board with it;
- with `--full`, `check --full`: every episode of every entry played again.

The targets (issue 27): the default check under 5 minutes, the addition and its check
under 5 minutes, on a 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

BOARD = Path(__file__).resolve().parents[1] / "leaderboards"
# `bbbench` with the one check a board of copies fails lifted: one policy twice.
COPIES_ALLOWED = (
    "import sys; import bbbench.leaderboard.generation as g, bbbench.leaderboard.submissions "
    "as s; s.check_distinct = g.check_distinct = lambda runs: None; "
    "from bbbench.cli import main; sys.argv[0] = 'bbbench'; sys.exit(main(sys.argv[1:]))"
)


def synthetic_board(root: Path, entries: int) -> None:
    """`root` as a board of `entries` entries: the real ones, then copies of them."""
    if root.exists():
        shutil.rmtree(root)
    (root / "submissions").mkdir(parents=True)
    (root / "results").mkdir()
    real = sorted(path.name for path in (BOARD / "submissions").iterdir())
    copy = 0
    while len(list((root / "submissions").iterdir())) < entries:
        for slug in real:
            if len(list((root / "submissions").iterdir())) >= entries:
                break
            new = slug if copy == 0 else f"{slug}-copy{copy}"
            shutil.copytree(BOARD / "submissions" / slug, root / "submissions" / new)
            metadata_path = root / "submissions" / new / "submission.json"
            metadata = json.loads(metadata_path.read_text())
            if copy:
                metadata["name"] = f"{metadata['name']} (copy {copy})"[:60]
            metadata_path.write_text(json.dumps(metadata, indent=2) + "\n")
            runs = BOARD / "submissions" / slug / "runs"
            names = [f"-{run.name}" for run in sorted(runs.iterdir())] if runs.is_dir() else [""]
            for run in names:  # each run's results and profiles
                for source in (BOARD / "results").glob(f"{slug}{run}.*json"):
                    suffix = source.name.removeprefix(f"{slug}{run}")
                    if suffix == ".json" or suffix.endswith(".profile.json"):
                        shutil.copyfile(source, root / "results" / f"{new}{run}{suffix}")
        copy += 1


def timed(*argv: str) -> tuple[float, str]:
    began = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", COPIES_ALLOWED, "leaderboard", *argv],
        capture_output=True,
        text=True,
    )
    seconds = time.perf_counter() - began
    if done.returncode != 0:
        raise SystemExit(
            f"bbbench leaderboard {' '.join(argv)} failed:\n{done.stdout}{done.stderr}"
        )
    return seconds, done.stdout.strip().splitlines()[-1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--entries", type=int, default=100)
    parser.add_argument("--root", type=Path, default=Path("/tmp/bbbench-synthetic"))
    parser.add_argument("--full", action="store_true", help="also time check --full (long)")
    args = parser.parse_args()
    board = args.root / "leaderboards"
    synthetic_board(board, args.entries)
    root = ["--root", str(board)]
    for label, argv in (("build from the records", ["build", *root]), ("check", ["check", *root])):
        seconds, said = timed(*argv)
        print(f"{label}: {seconds:.0f} s ({said})", flush=True)
    shutil.copytree(BOARD / "submissions" / "lqr", board / "submissions" / "added")
    seconds_build, said = timed("build", *root)
    print(f"add one entry (build): {seconds_build:.0f} s ({said})", flush=True)
    seconds_check, said = timed("check", *root)
    print(f"then check: {seconds_check:.0f} s ({said})", flush=True)
    print(f"add and check: {seconds_build + seconds_check:.0f} s", flush=True)
    if args.full:
        seconds, said = timed("check", "--full", *root)
        print(f"check --full: {seconds:.0f} s ({said})", flush=True)


if __name__ == "__main__":
    main()

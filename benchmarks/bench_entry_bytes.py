"""The bytes a board entry (one run) takes in git, at two commits: its records (its
results, its robustness profiles, its run.json, its training's files in baselines/) and
its policy (the submitted file and statistics), and the bytes of leaderboards/ and
baselines/ in all. Read from git's trees (`git ls-tree -l`): nothing is played.

    python benchmarks/bench_entry_bytes.py --before 4b74679 [--after HEAD] [SLUG ...]
"""

from __future__ import annotations

import argparse
import subprocess
from collections.abc import Iterable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
POLICY_FILES = ("policy.zip", "policy.onnx", "vecnormalize.pkl")
DEFAULT_SLUGS = (
    "ippo-swap-v0-3m-s0",  # a MARL run: two tracks' profiles
    "mappo-beamcarry-v0-3m-s1",
    "sac-leggedvelocitytracking-v0-s1",
    "ppo-bumps-v2-s0",
)


def sizes(commit: str) -> dict[str, int]:
    """Every file's size in bytes at `commit`, by path."""
    listing = subprocess.run(
        ["git", "ls-tree", "-r", "-l", commit, "leaderboards", "baselines"],
        cwd=ROOT, check=True, capture_output=True, text=True,
    ).stdout  # fmt: skip
    tree = {}
    for line in listing.splitlines():
        meta, path = line.split("\t", 1)
        tree[path] = int(meta.split()[3])
    return tree


def entry_files(tree: Iterable[str], slug: str) -> list[str]:
    """The files of run `slug` (`<method>-s<seed>`): its results and profiles, its run
    folder in its method's submission, and its training's folder."""
    method, seed = slug.rsplit("-s", 1)
    prefixes = (
        f"leaderboards/results/{slug}.",
        f"leaderboards/submissions/{method}/runs/s{seed}/",
        f"baselines/{slug}/",
    )
    return [path for path in tree if path.startswith(prefixes)]


def split(tree: dict[str, int], files: list[str]) -> tuple[int, int]:
    """(records, policy) bytes of `files`."""
    policy = sum(tree[path] for path in files if path.endswith(POLICY_FILES))
    return sum(tree[path] for path in files) - policy, policy


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", required=True, help="a commit")
    parser.add_argument("--after", default="HEAD", help="a commit (default HEAD)")
    parser.add_argument("slugs", nargs="*", default=list(DEFAULT_SLUGS))
    args = parser.parse_args()
    before, after = sizes(args.before), sizes(args.after)
    print(f"| entry | records at {args.before} | records at {args.after} | policy |")
    print("|---|---:|---:|---:|")
    for slug in args.slugs:
        old, _ = split(before, entry_files(before, slug))
        new, policy = split(after, entry_files(after, slug))
        print(f"| {slug} | {old / 1e3:.0f} KB | {new / 1e3:.0f} KB | {policy / 1e3:.0f} KB |")
    print(f"\n| folder | at {args.before} | at {args.after} |")
    print("|---|---:|---:|")
    for folder in ("leaderboards/results", "leaderboards/submissions", "leaderboards", "baselines"):
        old, new = (
            sum(n for p, n in t.items() if p.startswith(folder + "/")) for t in (before, after)
        )
        print(f"| {folder}/ | {old / 1e6:.1f} MB | {new / 1e6:.1f} MB |")
    old, new = (sum(t.values()) for t in (before, after))
    print(f"| both | {old / 1e6:.1f} MB | {new / 1e6:.1f} MB |")


if __name__ == "__main__":
    main()

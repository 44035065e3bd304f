"""Every stable-baselines3 zip on the board and shipped with bbbench, exported with
`bbbench export`, against its zip: the same episodes, byte for byte.

    python scripts/export_parity.py [--episodes 5] [--root leaderboards]

For each zip (leaderboards/submissions/*/policy.zip with its vecnormalize.pkl, and the
zips shipped in bbbench/policies/), it writes the ONNX export (which is itself refused
unless the graph acts as the zip on 4096 observations) and plays the first N
evaluation seeds of every latest task the policy fits with both, comparing the
episodes' records (return, length, falls, velocity error: every digit). Prints one
line per zip and exits 1 if any differs.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from bbbench.evaluation import evaluate
from bbbench.policies import export_zip, fitting_tasks, load_policy
from bbbench.policies.registry import REFERENCE_POLICY, TERRAIN_POLICIES

ROOT = Path(__file__).resolve().parents[1]


def zips(root: Path) -> list[tuple[str, Path, Path | None]]:
    found = []
    for path in sorted((root / "submissions").glob("*/policy.zip")):
        statistics = path.with_name("vecnormalize.pkl")
        found.append((path.parent.name, path, statistics if statistics.exists() else None))
    shipped = {"reference": REFERENCE_POLICY, **TERRAIN_POLICIES}
    found += [(name, path, None) for name, path in shipped.items()]
    return found


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument("--root", type=Path, default=ROOT / "leaderboards")
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp())
    differing = 0
    for name, path, statistics in zips(args.root):
        began = time.perf_counter()
        zipped = load_policy(path, vecnormalize=statistics)
        exported = load_policy(export_zip(zipped, folder / f"{name}.onnx"))
        tasks = fitting_tasks(zipped)
        same = all(
            evaluate(exported, [task], episodes=args.episodes, workers=1).document["tasks"]
            == evaluate(zipped, [task], episodes=args.episodes, workers=1).document["tasks"]
            for task in tasks
        )
        differing += not same
        print(
            f"{'same' if same else 'DIFFERENT'}: {name} ({zipped.algorithm}, "
            f"{zipped.spaces_text()}{', VecNormalize' if statistics else ''}), "
            f"{len(tasks)} task(s) x {args.episodes} episodes, "
            f"{time.perf_counter() - began:.0f} s",
            flush=True,
        )
    print(f"{differing} of {len(zips(args.root))} zips play otherwise from ONNX")
    return 1 if differing else 0


if __name__ == "__main__":
    sys.exit(main())

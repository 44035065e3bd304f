"""Draw each training run's curve.png from its records (curve.json and train.json), as
`bbbench train` draws it at the end of a training.

The figures are not kept in git: they are drawn from curve.json, which is. A fresh
clone draws them with

    python scripts/draw_curves.py            # every run under baselines/
    python scripts/draw_curves.py baselines/ppo-bumps-v2-s0
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from bbbench.files import write_atomic
from bbbench.training.logs import curve_png

ROOT = Path(__file__).resolve().parents[1]


def draw(folder: Path) -> Path:
    """`folder/curve.png` from the run's curve.json and train.json."""
    curve = json.loads((folder / "curve.json").read_text())["points"]
    record = json.loads((folder / "train.json").read_text())
    out = folder / "curve.png"
    write_atomic(out, curve_png(curve, record["tasks"], record["recipe"]["algorithm"]))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "runs", nargs="*", type=Path, help="run folders (default: every run under baselines/)"
    )
    args = parser.parse_args(argv)
    runs = args.runs or sorted(p.parent for p in (ROOT / "baselines").glob("**/curve.json"))
    missing = [str(run) for run in runs if not (run / "curve.json").is_file()]
    if missing:
        parser.error(f"no curve.json in {', '.join(missing)}; give a training run's folder")
    for run in runs:
        if not (run / "train.json").is_file():
            print(f"{run}: no train.json beside its curve.json; skipped", file=sys.stderr)
            continue
        print(draw(run))
    return 0


if __name__ == "__main__":
    sys.exit(main())

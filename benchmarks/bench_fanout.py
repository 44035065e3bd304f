"""Ray fan-out: two trainings as Ray tasks on this machine against one training alone.

    python benchmarks/bench_fanout.py [--steps 30000] [--rounds 2]

One training: `bbbench train bbbench/FlatBalance-v1 --algo ppo --steps N --seed 0`, the
whole command timed. Fan-out: `--seeds 0,1 --backend ray`, the whole command (Ray's
start included). Throughput: training steps per second of wall time (2N for the
fan-out); the ratio fan-out / one, per round. Run it on a quiet machine.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

TASK = "bbbench/FlatBalance-v1"


def timed(argv: list[str]) -> float:
    began = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - began


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=30_000)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    common = ["bbbench", "train", TASK, "--algo", "ppo", "--steps", str(args.steps)]
    common += ["--eval-episodes", "2"]
    rounds = []
    for _ in range(args.rounds):
        with tempfile.TemporaryDirectory() as folder:
            one = timed([*common, "--seed", "0", "--out", str(Path(folder) / "one.zip")])
            out = str(Path(folder) / "two.zip")
            two = timed([*common, "--seeds", "0,1", "--backend", "ray", "--out", out])
        rounds.append(
            {
                "one_s": round(one, 1),
                "fanout_s": round(two, 1),
                "one_steps_per_s": round(args.steps / one),
                "fanout_steps_per_s": round(2 * args.steps / two),
                "ratio": (2 * args.steps / two) / (args.steps / one),
            }
        )
    report = {"steps": args.steps, "rounds": rounds}
    report["median_ratio"] = statistics.median(r["ratio"] for r in rounds)
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()

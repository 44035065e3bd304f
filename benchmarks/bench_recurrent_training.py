"""What the recurrence costs a training: whole IPPO-GRU trainings against IPPO's, on the
message task, in world steps per second.

    python benchmarks/bench_recurrent_training.py [--batches 3] [--rounds 2]

Both run `Experiment.run` of their shipped recipe (`ippo.yml`: the neighbour encoder as
the actor; `ippo-gru.yml`: BenchMARL's GRU of 128 and an MLP of 256, 256) for
`--batches` of its batches (6,000 world steps from 10 worlds, in 2 worker processes), as
`bbbench train` runs them: the same collection, the same critic, the same 10 passes over
each batch; only the actor differs, and how BenchMARL feeds it (a recurrent actor
trains on whole trajectories, a minibatch of one world's 600 steps in order). A round
times both, the order turning round by round; the ratio is within a round. Run it on a
quiet machine.
"""

from __future__ import annotations

import argparse
import json
import statistics

import torch
from bench_marl import ippo_rate

TASK = "bbbench/Rendezvous-v0"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batches", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--task", default=TASK)
    args = parser.parse_args()
    torch.set_num_threads(1)
    rounds = []
    for index in range(args.rounds):
        order = ("ippo", "ippo-gru") if index % 2 == 0 else ("ippo-gru", "ippo")
        rates = {algo: ippo_rate(args.batches, None, algo, args.task) for algo in order}
        rounds.append(
            {
                **{f"{algo}_bot_steps_per_s": round(rate) for algo, rate in rates.items()},
                "gru_seconds_per_step_to_mlp": round(rates["ippo"] / rates["ippo-gru"], 2),
            }
        )
    report = {"task": args.task, "batches": args.batches, "rounds": rounds}
    report["median"] = statistics.median(r["gru_seconds_per_step_to_mlp"] for r in rounds)
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()

"""A GRU policy's ONNX evaluation against its MLP twin's (issue 67: at most 2.0).

    python benchmarks/bench_recurrent.py [--episodes 4] [--rounds 5] [--hidden 64]
    python benchmarks/bench_recurrent.py --trained GRU.onnx MLP.onnx --task bbbench/Rendezvous-v0

Two ONNX policies for MultiBalance-v1 (17 values in, 9 actions out), exported with
`onnx_bytes` from torch modules of the same widths: the twin, a layer of `--hidden` tanh
units and a linear head; the recurrent one, a GRU of `--hidden` units (its state carried
by the play loops, `bbbench.recurrent_state`) and the same head. Each round, in turns:

- `evaluate`: both on the task's first `--episodes` evaluation seeds in this process
  (one worker), seconds per env step of the whole call (resets, the env, the results);
- `actor`: each actor alone on `--calls` batches of 4 observations (a world of 4 bots),
  seconds per call (the GRU's `step` with its states, the twin's call).

Each ratio is the median over rounds of the GRU's time over the twin's. The untrained
networks' bots fall within a second, so `evaluate` counts resets more than a trained
policy's episodes would: `actor` is the policy's own share. `--trained` times two trained
files of one task instead (a recurrent one first, e.g. IPPO-GRU's against IPPO's).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import torch

import bbbench
from bbbench.evaluation import evaluate
from bbbench.policies import load_policy
from bbbench.policies.onnx.export import onnx_bytes
from bbbench.policies.onnx.policy import OnnxPolicy
from bbbench.policies.onnx.reader import parse_onnx

TASK = "bbbench/MultiBalance-v1"


class Twin(torch.nn.Module):
    def __init__(self, hidden: int) -> None:
        super().__init__()
        self.layer, self.head = torch.nn.Linear(17, hidden), torch.nn.Linear(hidden, 9)

    def forward(self, obs):
        return self.head(torch.tanh(self.layer(obs)))


class Recurrent(torch.nn.Module):
    def __init__(self, hidden: int) -> None:
        super().__init__()
        self.gru, self.head = torch.nn.GRU(17, hidden), torch.nn.Linear(hidden, 9)

    def forward(self, obs, state):
        out, last = self.gru(obs.unsqueeze(0), state.unsqueeze(0))
        return self.head(out[0]), last[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=4)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--hidden", type=int, default=64)
    parser.add_argument("--calls", type=int, default=3000)
    parser.add_argument("--trained", nargs=2, metavar=("GRU", "MLP"), help="two policy files")
    parser.add_argument("--task", default=TASK, help="with --trained: the task they play")
    args = parser.parse_args()
    torch.manual_seed(0)
    task = TASK
    if args.trained:
        task = args.task
        policies = {"gru": load_policy(args.trained[0]), "mlp": load_policy(args.trained[1])}
    else:
        policies = {
            "mlp": OnnxPolicy(parse_onnx(onnx_bytes(Twin(args.hidden).eval(), TASK), "mlp", "m")),
            "gru": OnnxPolicy(
                parse_onnx(
                    onnx_bytes(Recurrent(args.hidden).eval(), TASK, state_width=args.hidden),
                    "gru",
                    "gru",
                )
            ),
        }
    bots = bbbench.spec(task).group.n_bots
    env = bbbench.make_parallel(task)
    width = env.observation_space(env.possible_agents[0]).shape[0]
    env.close()
    batches = np.random.default_rng(0).normal(size=(args.calls, bots, width)).astype(np.float32)
    per_step: dict[str, list[float]] = {name: [] for name in policies}
    per_call: dict[str, list[float]] = {name: [] for name in policies}
    for _ in range(args.rounds):
        for name, policy in policies.items():
            began = time.perf_counter()
            played = evaluate(policy, [task], episodes=args.episodes, workers=1)
            per_step[name].append((time.perf_counter() - began) / played.steps)
            actor = policy.actor(task)
            if name == "gru":
                states = actor.initial_state(bots)
                began = time.perf_counter()
                for batch in batches:
                    _, states = actor.step(batch, states)
            else:
                began = time.perf_counter()
                for batch in batches:
                    actor(batch)
            per_call[name].append((time.perf_counter() - began) / args.calls)
    for label, times in (("evaluate", per_step), ("actor", per_call)):
        ratios = [g / m for g, m in zip(times["gru"], times["mlp"], strict=True)]
        print(
            f"{label}: MLP twin {statistics.median(times['mlp']) * 1e6:.1f} us, GRU "
            f"{statistics.median(times['gru']) * 1e6:.1f} us; GRU / twin "
            f"{statistics.median(ratios):.2f} (min {min(ratios):.2f}, max {max(ratios):.2f}, "
            f"{args.rounds} rounds)"
        )


if __name__ == "__main__":
    main()

"""ONNX policies: an exported MLP scored from ONNX against its zip, and a neighbour
encoder's act cost per bot-step.

    python benchmarks/bench_onnx.py [--episodes 10] [--rounds 3]

1. Throughput: `evaluate(policy, tasks, episodes=N, workers=1)` in this process for
   a zip and the same policy exported by `bbbench export`: the reference PPO (a plain
   MLP) on FlatBalance-v1 and VelocityTracking-v1, and the BeamCarry-v0 PPO of the
   board (VecNormalize, folded into the graph in float64) on BeamCarry-v0; environment
   steps (bot-steps) per second. The two runs alternate within each round; the ratio
   ONNX / zip is taken per round.
2. Act cost: microseconds per call of each actor on the observations of 8 bots of
   MultiBalance-v1 (17 values each), per bot-step: the neighbour encoder
   (`bbbench.policies.encoder`: 3 slots of 4 values, 32 features each, mean-pooled,
   then 64 x 64 tanh) exported to ONNX; the shared PPO MLP of the multi-bot board
   (ppo-multibalance-v1-s0, VecNormalize folded in) from its zip and from ONNX; and the
   environment's own step per bot, for scale.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

import bbbench
from bbbench.evaluation import evaluate
from bbbench.policies import export_onnx, export_zip, load_policy
from bbbench.policies.encoder import neighbour_encoder

TASKS = ["bbbench/FlatBalance-v1", "bbbench/VelocityTracking-v1"]
MULTI = "bbbench/MultiBalance-v1"
ROOT = Path(__file__).resolve().parents[1]
BOARD_PPO = ROOT / "leaderboards" / "submissions" / "ppo-multibalance-v1-s0"


def throughput(policy, tasks: list[str], episodes: int) -> float:
    began = time.perf_counter()
    played = evaluate(policy, tasks, episodes=episodes, workers=1)
    return played.steps / (time.perf_counter() - began)


def per_call(actor, observations: np.ndarray, calls: int = 2000) -> float:
    """Microseconds per call, best of 3."""
    best = float("inf")
    for _ in range(3):
        began = time.perf_counter()
        for _ in range(calls):
            actor(observations)
        best = min(best, (time.perf_counter() - began) / calls)
    return best * 1e6


def multi_observations(bots: int, steps: int = 200) -> np.ndarray:
    """Observations 8 bots of MultiBalance-v1 saw under PD, (steps, bots, 17)."""
    env = bbbench.make_parallel(MULTI, n_bots=bots)
    observations, _ = env.reset(seed=0)
    pd = load_policy("pd").actor(MULTI)
    seen = []
    for _ in range(steps):
        if len(observations) < bots:
            observations, _ = env.reset()
        rows = np.stack([observations[a] for a in sorted(observations)])
        seen.append(rows)
        actions = dict(zip(sorted(observations), pd(rows), strict=True))
        observations, *_ = env.step(actions)
    return np.stack(seen)


def env_step_per_bot(bots: int, steps: int = 300) -> float:
    env = bbbench.make_parallel(MULTI, n_bots=bots)
    env.reset(seed=0)
    began, taken = time.perf_counter(), 0
    while taken < steps:
        if not env.agents:
            env.reset()
        env.step({agent: 4 for agent in env.agents})
        taken += 1
    return (time.perf_counter() - began) / steps / bots * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp())
    team = ROOT / "leaderboards" / "submissions" / "ppo-beamcarry-v0-s0"
    pairs = {  # name: (the zip, its tasks)
        "reference PPO (plain MLP)": (load_policy("reference"), TASKS),
        "PPO BeamCarry-v0 seed 0 (VecNormalize, 3 bots)": (
            load_policy(team / "policy.zip", vecnormalize=team / "vecnormalize.pkl"),
            ["bbbench/BeamCarry-v0"],
        ),
    }
    rounds = {name: [] for name in pairs}
    for name, (zipped, tasks) in pairs.items():
        exported = load_policy(export_zip(zipped, folder / "exported.onnx"))
        for _ in range(args.rounds):
            zip_rate = throughput(zipped, tasks, args.episodes)
            onnx_rate = throughput(exported, tasks, args.episodes)
            rounds[name].append({"zip": zip_rate, "onnx": onnx_rate, "ratio": onnx_rate / zip_rate})
    torch.manual_seed(0)
    encoder = neighbour_encoder(5, 3, 4, 9)
    encoded = load_policy(export_onnx(encoder, MULTI, folder / "encoder.onnx"))
    board = load_policy(BOARD_PPO / "policy.zip", vecnormalize=BOARD_PPO / "vecnormalize.pkl")
    board_onnx = load_policy(export_zip(board, folder / "board.onnx"))
    seen = multi_observations(8)
    batch = seen[100]
    costs = {
        "neighbour encoder (ONNX)": per_call(encoded.actor(MULTI), batch) / 8,
        "shared PPO MLP 64x64 (zip, VecNormalize)": per_call(board.actor(MULTI), batch) / 8,
        "shared PPO MLP 64x64 (ONNX)": per_call(board_onnx.actor(MULTI), batch) / 8,
        "MultiBalance-v1 env step, per bot": env_step_per_bot(8),
    }
    report = {
        "rounds": rounds,
        "median_ratio": {
            name: statistics.median(r["ratio"] for r in runs) for name, runs in rounds.items()
        },
        "act_us_per_bot_step_8_bots": costs,
    }
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()

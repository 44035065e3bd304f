"""The mixed team's step against BeamCarry-v0's (issue 67: at most 1.5).

    python benchmarks/bench_mixed.py [--bots 3 4] [--bot-steps 30000] [--chunk 3000]

Each task in one process, its classical controller acting (mixed-team; team on
BeamCarry-v0), both in continuous actions (the only mode the mixed team takes), only
the env's `step` timed (resets and the controllers excluded); the two tasks take turns
in chunks of bot-steps, so they share the machine's slow and fast phases. The ratio is
MixedBeamCarry-v0's seconds per bot-step over BeamCarry-v0's: what the wheel-legged
robots' legs (four servos each, a body of seven links against three) and their wider
observation cost beside two-wheel bots.
"""

from __future__ import annotations

import argparse

from bench_channel import Loop, in_turns

TASKS = (("bbbench/MixedBeamCarry-v0", "mixed-team"), ("bbbench/BeamCarry-v0", "team"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bots", type=int, nargs="*", default=[3, 4])
    parser.add_argument("--bot-steps", type=int, default=30_000)
    parser.add_argument("--chunk", type=int, default=3_000)
    args = parser.parse_args()
    print("bots | MixedBeamCarry-v0 us/bot-step | BeamCarry-v0 us/bot-step | ratio")
    for bots in args.bots:
        loops = [
            Loop(task_id, controller, bots, action_mode="continuous")
            for task_id, controller in TASKS
        ]
        mixed, beam = in_turns(loops, args.bot_steps, args.chunk)
        print(f"{bots} | {mixed * 1e6:.1f} | {beam * 1e6:.1f} | {mixed / beam:.3f}")


if __name__ == "__main__":
    main()

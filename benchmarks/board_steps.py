"""What a `bbbench leaderboard check` plays, read from the stored results (no episode is
played): episodes and bot-steps by task and by entry. A check's time is close to
proportional to its bot-steps (the harness's cost per step is the same for every entry),
so this shows where the time goes and compares two boards without timing either.

    python benchmarks/board_steps.py [--root leaderboards] [--vs OTHER_ROOT] [--top 10]
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path

from bbbench.evaluation.results import read


def steps(root: Path) -> tuple[Counter, Counter, int]:
    """Bot-steps by task and by entry, and the episodes, of the results in `root`."""
    by_task: Counter = Counter()
    by_entry: Counter = Counter()
    episodes = 0
    for path in sorted((root / "results").glob("*.json")):
        if path.name.endswith(".profile.json"):
            continue
        for block in read(path)["tasks"]:
            played = sum(episode["length"] for episode in block["episodes"]) * block["bots"]
            by_task[block["task"]] += played
            by_entry[path.stem] += played
            episodes += len(block["episodes"])
    return by_task, by_entry, episodes


def _summary(root: Path, top: int) -> int:
    by_task, by_entry, episodes = steps(root)
    total = sum(by_task.values())
    print(f"{root}: {len(by_entry)} entries, {len(by_task)} tasks, {episodes} episodes, "
          f"{total / 1e6:.2f}M bot-steps")  # fmt: skip
    for task_id, count in by_task.most_common():
        print(f"  {task_id:32} {count / 1e6:6.2f}M  {count / total:6.1%}")
    for slug, count in by_entry.most_common(top):
        print(f"  {slug:32} {count / 1e6:6.2f}M  {count / total:6.1%}")
    return total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=Path("leaderboards"))
    parser.add_argument("--vs", type=Path, help="another board's folder, to compare with")
    parser.add_argument("--top", type=int, default=10, help="entries to list")
    args = parser.parse_args()
    total = _summary(args.root, args.top)
    if args.vs is not None:
        other = _summary(args.vs, args.top)
        print(f"{args.root} / {args.vs}: {total / other:.3f} of the bot-steps")


if __name__ == "__main__":
    main()

"""Re-make the board's team-task records with each episode's cause and the bots that
fell (issue 51): before, a team's end was recorded as `falls = n_bots`, whatever ended it.

    python scripts/remake_team_causes.py [--root leaderboards] [--workers 2]
    bbbench leaderboard build        # the documents made again from the records

An episode recorded with no fall and no failure played to the time limit (any team end
recorded falls), so its cause is "time limit" and nothing is played. Every other
episode is played again, and its new record replaces the old one only if it agrees
with it in everything the old one held but the fall count (return, length, success,
metrics and failure); a disagreement stops the script before anything is written.
Entries whose records already hold causes are left alone.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bbbench.evaluation.harness import play_draws
from bbbench.evaluation.play import TIME_LIMIT
from bbbench.evaluation.results import dumps, read
from bbbench.leaderboard.generation import DEFAULT_BOARD, RESULTS, SUBMISSIONS
from bbbench.leaderboard.submissions import read_methods
from bbbench.tasks.suite import spec

PROFILE = ".profile.json"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--root", type=Path, default=Path("leaderboards"))
    parser.add_argument("--workers", type=int, default=None)
    args = parser.parse_args(argv)
    documents, draws = {}, []  # path: document; (policy, task, seed, the record to replace)
    runs = [run for method in read_methods(args.root / SUBMISSIONS) for run in method.runs]
    for submission in runs:
        policy = None
        for path in sorted((args.root / RESULTS).glob(f"{submission.slug}.*json")):
            if path.name != f"{submission.slug}.json" and not path.name.endswith(PROFILE):
                continue
            document = read(path)
            policy = policy or submission.load_policy()
            found = list(_team_records(document, policy))
            pending = [(task, r) for task, r in found if "cause" not in r and r["failure"] is None]
            if not pending:
                continue
            documents[path] = document
            for task, record in pending:
                if record["falls"] == 0:
                    record["cause"] = TIME_LIMIT
                else:
                    draws.append((policy, task, record["seed"], record))
    print(f"{len(documents)} documents; {len(draws)} episodes to play again", flush=True)
    played = play_draws([(p, t, s) for p, t, s, _ in draws], workers=args.workers)
    for (_, task, seed, old), episode in zip(draws, played, strict=True):
        if episode is None:
            sys.exit(f"{task.id} seed {seed}: its worker died twice; nothing written")
        new = episode.record()
        kept = {key: value for key, value in old.items() if key != "falls"}
        if {key: new[key] for key in kept} != kept:
            sys.exit(f"{task.id} seed {seed}: recorded {old}, replayed {new}; nothing written")
        old.clear()
        old.update(new)
    for path, document in documents.items():
        path.write_text(dumps(document))
    print(f"wrote {len(documents)} documents: now run `bbbench leaderboard build`")
    return 0


def _team_records(document: dict, policy):
    """(the spec played, the record) of every team-task episode of a results or profile
    document."""
    if "axes" in document:  # a profile: each point's spec, in the protocol's order
        task_id = document["protocol"]["task"]
        if not spec(task_id).scenario_class.team:
            return
        points = [point for block in document["axes"] for point in block["points"]]
        specs = DEFAULT_BOARD.profile.specs(task_id, policy.height_scan)
        for point, (_, _, task) in zip(points, specs, strict=True):
            for record in point["episodes"]:
                yield task, record
        return
    for block in document["tasks"]:
        task = spec(block["task"]).with_height_scan(policy.height_scan)
        if task.scenario_class.team:
            for record in block["episodes"]:
                yield task, record


if __name__ == "__main__":
    sys.exit(main())

"""What adding a trained run to the board takes, for scripts/train_baselines.py: the
method a run belongs to, whether it is on the board, its budget in world steps, the
board to one process while it adds, and its results.json dropped once the board holds
the same episodes; and the seeds, the campaign's budget and its cells of their own
recipes (messages muted, continuous actions), which scripts/marl_tables.py and
marl_curves.py name too."""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import tempfile
from pathlib import Path

from bbbench.evaluation.results import read
from bbbench.tasks.suite import spec

# The seeds a method trains (and scripts/marl_tables.py and marl_curves.py read), and
# the MARL baselines at the field's budget (issue 50): each cell's seeds one after another.
SEEDS = (0, 1, 2)
CAMPAIGN_BUDGET = "3m"


def short(task_id: str) -> str:
    """A task's ID without the suite's prefix: "Rendezvous-v0", as the tables name it."""
    return task_id.removeprefix("bbbench/")


def cell_slug(method: str, task_id: str) -> str:
    """A campaign cell's slug, its runs' stem (`<slug>-s<seed>`): the method (an
    algorithm, or a recipe of its own such as `mappo-muted`), the task, the budget."""
    return f"{method}-{short(task_id).lower()}-{CAMPAIGN_BUDGET}"


MUTED = {  # issue 67's run with the messages muted: MAPPO's recipe, `mute_messages` added
    "cell": cell_slug("mappo-muted", "bbbench/Rendezvous-v0"),
    "algo": "mappo",
    "tasks": ["bbbench/Rendezvous-v0"],
    "seeds": SEEDS,
    "recipe": "baselines/recipes/mappo-muted-rendezvous.yml",
    "name": "MAPPO Rendezvous-v0, messages muted",
}
CONTINUOUS = {  # issue 67's IPPO in continuous actions: IPPO's recipe, the action mode changed
    "cell": cell_slug("ippo-continuous", "bbbench/Rendezvous-v0"),
    "algo": "ippo",
    "tasks": ["bbbench/Rendezvous-v0"],
    "seeds": SEEDS,
    "recipe": "baselines/recipes/ippo-continuous-rendezvous.yml",
    "name": "IPPO Rendezvous-v0, continuous actions",
}
# The campaign's cells of a recipe of their own (its file and method name), after the
# shipped recipes' cells.
VARIANTS = (MUTED, CONTINUOUS)


def method_slug(run: dict) -> str:
    """The method a run belongs to: its slug without the seed."""
    return run["slug"].rsplit("-s", 1)[0]


def on_board(board: Path, run: dict) -> bool:
    return (board / "submissions" / method_slug(run) / "runs" / f"s{run['seed']}").exists()


def world_steps(record: dict) -> int:
    """A training's budget in world steps: BenchMARL counts them (and records bot-steps
    beside); stable-baselines3 counts bot-steps on a multi-bot task (a world step is
    n_bots samples)."""
    task = spec(record["tasks"][0])
    if "bot_steps" in record or not task.multi_agent:
        return record["steps"]
    return record["steps"] // task.group.n_bots


def drop_repeated_results(folder: Path, board: Path) -> bool:
    """Remove the run's results.json when the board's results of the run hold the same
    episodes of every task it played (the board keeps them; `run_episodes` reads them
    there). A record made before teams recorded what ended them lacks `cause` and is the
    same without it. True if removed."""
    own, theirs = folder / "results.json", board / "results" / f"{folder.name}.json"
    if not (own.is_file() and theirs.is_file()):
        return False
    boards = {block["task"]: block for block in read(theirs)["tasks"]}
    for block in read(own)["tasks"]:
        other = boards.get(block["task"])
        if other is None or len(other["episodes"]) != len(block["episodes"]):
            return False
        for mine, kept in zip(block["episodes"], other["episodes"], strict=True):
            if mine != kept and ("cause" in mine or {**mine, "cause": kept.get("cause")} != kept):
                return False
    own.unlink()
    return True


@contextlib.contextmanager
def board_lock(board: Path):
    """The board to this caller alone while it adds (campaign cells may run as two
    processes side by side, `--parallel` runs as threads: each call opens the lock file
    anew, so threads exclude each other too; `add` rebuilds the board and `git rm` takes
    git's index)."""
    key = hashlib.sha256(str(board.resolve()).encode()).hexdigest()[:16]
    with open(Path(tempfile.gettempdir()) / f"bbbench-adding-{key}.lock", "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)

"""The board's records say what the code and the runs' own records say (issue 65): no
record names a module that is gone, and no run's wall time drifts from its log."""

from __future__ import annotations

import importlib
import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SUBMISSIONS = sorted((ROOT / "leaderboards" / "submissions").iterdir())
DOTTED = re.compile(r"\bbbbench(?:\.[A-Za-z_]\w*)+")


def submission(folder: Path) -> dict:
    return json.loads((folder / "submission.json").read_text())


def runs() -> dict[str, dict]:
    """Every run of the board by its slug: its records (run.json, or a one-run method's
    own submission.json)."""
    found = {}
    for folder in SUBMISSIONS:
        if (folder / "runs").is_dir():
            for run in sorted((folder / "runs").iterdir()):
                found[f"{folder.name}-{run.name}"] = json.loads((run / "run.json").read_text())
        else:
            found[folder.name] = submission(folder)
    return found


RUNS = runs()


def importable(dotted: str) -> bool:
    """A module, or an attribute of one."""
    module, _, attribute = dotted.rpartition(".")
    for name, rest in ((dotted, None), (module, attribute)):
        try:
            found = importlib.import_module(name)
        except ImportError:
            continue
        return rest is None or hasattr(found, rest)
    return False


@pytest.mark.parametrize("slug", sorted(RUNS))
def test_every_code_path_a_run_names_exists(slug):
    data = RUNS[slug]
    text = " ".join(str(data.get(key, "")) for key in ("command", "notes", "wall_time"))
    named = DOTTED.findall(text)
    assert [path for path in named if not importable(path)] == []


def test_the_five_built_ins_that_named_moved_modules_name_them_now():
    named = {slug: DOTTED.findall(record["command"]) for slug, record in RUNS.items()}
    assert named["lqr"] == [
        "bbbench.policies.controllers.lqr.LQRController",
        "bbbench.policies.controllers.lqr",
    ]
    assert named["random"] == ["bbbench.policies.controllers.builtin.RandomPolicy"]


@pytest.mark.parametrize(
    "slug", [slug for slug in sorted(RUNS) if (ROOT / "baselines" / slug / "train.json").is_file()]
)
def test_a_runs_wall_time_is_what_its_training_recorded(slug):
    record = json.loads((ROOT / "baselines" / slug / "train.json").read_text())
    stated = RUNS[slug]["wall_time"]
    assert stated.startswith(f"{record['wall_time_s'] / 60:.0f} min"), (
        f"{slug}: {stated!r}, its train.json says {record['wall_time_s']:.0f} s"
    )
    hardware = RUNS[slug]["hardware"]
    if record.get("trainings_beside"):  # counted while it trained: what the record says
        from bbbench.training.beside import described

        assert described(record["trainings_beside"]) in hardware
    elif "side_by_side" in record:  # as the script ran them, for older records
        assert ("one training" in hardware) == (record["side_by_side"] in (1, "1"))


@pytest.mark.parametrize(
    "slug", [slug for slug in sorted(RUNS) if (ROOT / "baselines" / slug / "train.json").is_file()]
)
def test_a_runs_budget_is_in_world_steps_as_its_training_counted_them(slug):
    """One unit on the board: world steps (a multi-bot world step moves every bot once;
    stable-baselines3 counts bot-steps there, BenchMARL world steps)."""
    import bbbench

    record = json.loads((ROOT / "baselines" / slug / "train.json").read_text())
    task = bbbench.spec(record["tasks"][0])
    bots = task.group.n_bots if task.multi_agent and "bot_steps" not in record else 1
    assert RUNS[slug]["recipe"]["world_steps"] == record["steps"] // bots


def test_every_runs_results_are_todays_harness():
    """A run's own results (baselines/<slug>/results.json) are played as the board plays."""
    from bbbench.evaluation.results import HARNESS_VERSION

    old = [
        path.parent.name
        for path in sorted((ROOT / "baselines").glob("*/results.json"))
        if json.loads(path.read_text())["harness_version"] != HARNESS_VERSION
    ]
    assert old == []

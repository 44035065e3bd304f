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


@pytest.mark.parametrize("folder", SUBMISSIONS, ids=lambda folder: folder.name)
def test_every_code_path_a_submission_names_exists(folder):
    data = submission(folder)
    text = " ".join(str(data.get(key, "")) for key in ("command", "notes"))
    text += " " + data["training"]["wall_time"]
    named = DOTTED.findall(text)
    assert [path for path in named if not importable(path)] == []


def test_the_five_built_ins_that_named_moved_modules_name_them_now():
    named = {folder.name: DOTTED.findall(submission(folder)["command"]) for folder in SUBMISSIONS}
    assert named["lqr"] == [
        "bbbench.policies.controllers.lqr.LQRController",
        "bbbench.policies.controllers.lqr",
    ]
    assert named["random"] == ["bbbench.policies.controllers.builtin.RandomPolicy"]


@pytest.mark.parametrize(
    "folder",
    [
        folder
        for folder in SUBMISSIONS
        if (ROOT / "baselines" / folder.name / "train.json").is_file()
    ],
    ids=lambda folder: folder.name,
)
def test_a_runs_wall_time_is_what_its_training_recorded(folder):
    record = json.loads((ROOT / "baselines" / folder.name / "train.json").read_text())
    stated = submission(folder)["training"]["wall_time"]
    assert stated.startswith(f"{record['wall_time_s'] / 60:.0f} min"), (
        f"{folder.name}: {stated!r}, its train.json says {record['wall_time_s']:.0f} s"
    )
    one = "one training" in submission(folder)["training"]["hardware"]
    if "side_by_side" in record:
        assert one == (record["side_by_side"] in (1, "1"))

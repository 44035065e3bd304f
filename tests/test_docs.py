"""The task docstring documents what the code does: its tables follow the definitions."""

from __future__ import annotations

import json
import re
from pathlib import Path

import gymnasium as gym
import pytest

import bbbench
from bbbench.envs.balance import BalanceEnv
from bbbench.leaderboard.board import is_profile
from bbbench.robots import FALL_TILT
from bbbench.robots.layout import HEIGHT_SCAN_LAYOUT, SCAN_OFFSETS
from bbbench.robots.twowheel import OBSERVATION_LAYOUT, WHEEL_SPEED_CHANGES
from bbbench.tasks import reward as reward_module
from bbbench.tasks.reward import RewardWeights, StayUpReward

ROOT = Path(__file__).resolve().parents[1]
# The two-wheel bot's section of docs/robots.md (scripts/robots_doc.py writes it from
# the code): its tables live there and on the task pages, not in BalanceEnv's docstring.
ROBOTS_PAGE = (ROOT / "docs" / "robots.md").read_text()
TWO_WHEEL = ROBOTS_PAGE.split("## The two-wheel bot")[1].split("\n## ")[0]


def table_rows(heading: str) -> list[list[str]]:
    section = TWO_WHEEL.split(f"### {heading}")[1].split("### ")[0]
    rows = [line.strip() for line in section.splitlines() if line.strip().startswith("|")]
    return [[cell.strip() for cell in row.strip("|").split("|")] for row in rows[2:]]


def as_number(text: str) -> float:
    return {"pi": 3.141592653589793, "-pi": -3.141592653589793}.get(text) or float(text)


def test_observation_table_matches_the_layout():
    rows = table_rows("Observation Space")
    assert [row[1] for row in rows] == [field.name for field in OBSERVATION_LAYOUT]
    for row, field in zip(rows, OBSERVATION_LAYOUT, strict=True):
        assert as_number(row[2]) == pytest.approx(field.low, abs=1e-3)
        assert as_number(row[3]) == pytest.approx(field.high, abs=1e-3)
        assert row[4] == field.unit


def test_height_scan_table_matches_the_layout():
    rows = table_rows("Height Scan")
    assert [row[1] for row in rows] == [field.name for field in HEIGHT_SCAN_LAYOUT]
    for row, field, offset in zip(rows, HEIGHT_SCAN_LAYOUT, SCAN_OFFSETS, strict=True):
        assert float(row[2]) == pytest.approx(field.low)
        assert float(row[3]) == pytest.approx(field.high)
        assert row[4] == field.unit
        assert float(row[5].split()[0]) == pytest.approx(offset)


def test_action_table_matches_the_wheel_speed_changes():
    rows = table_rows("Action Space")
    assert [float(row[1]) for row in rows] == list(WHEEL_SPEED_CHANGES)


def test_the_robots_page_is_what_its_script_writes():
    from conftest import load_script

    assert load_script("robots_doc").text() == ROBOTS_PAGE, "run python scripts/robots_doc.py"


def test_reward_formulas_and_fall_limit_match_the_code():
    weights = RewardWeights()
    formula = (
        f"reward = {weights.upright} * (1 - |pitch|) - "
        f"{weights.velocity} * |forward_velocity - target_velocity|"
    )
    assert formula in reward_module.__doc__
    reward = StayUpReward()
    share, tail = reward.upright_share, reward.tail_share
    lines = (
        f"upright  = tolerance(|pitch|, bound {reward.pitch_bound} rad, "
        f"width {reward.pitch_width} rad)",
        f"near     = tolerance(|velocity_error|, bound {reward.velocity_bound} m/s, "
        f"width {reward.velocity_width} m/s)",
        f"toward   = ramp(|velocity_error|, bound {reward.velocity_bound} m/s, "
        f"width {reward.tail_width} m/s)",
        f"tracking = {1 - tail:g} * near + {tail:g} * toward",
        f"reward   = {reward.scale} * upright * ({share:g} + {1 - share:g} * tracking)",
    )
    for line in lines:
        assert line in reward_module.__doc__
    tasks_page = (ROOT / "docs" / "tasks.md").read_text()
    assert f"`reward_upright = {reward.scale * share:g} * upright`" in tasks_page
    assert re.search(rf"more than {FALL_TILT:g} rad", BalanceEnv.__doc__)


@pytest.mark.parametrize("task_id", bbbench.list_tasks(multi_agent=False))
def test_every_task_has_its_own_class_and_docstring_with_version_history(task_id):
    env = gym.make(task_id)
    cls = type(env.unwrapped)
    assert issubclass(cls, BalanceEnv)
    assert cls is not BalanceEnv
    doc = cls.__doc__
    assert task_id in doc
    history = doc.split("## Version History")[1]
    version = task_id.rsplit("-", 1)[1]
    assert re.search(rf"^\s*- {version}: \S", history, re.MULTILINE)
    assert all(entry in history for entry in bbbench.spec(task_id).version_history)
    # Made directly, the class plays its task's newest version (-v1 of Bumps, Obstacles).
    name = task_id.split("/")[1].rsplit("-", 1)[0]
    newest = max(t for t in bbbench.list_tasks() if t.split("/")[1].rsplit("-", 1)[0] == name)
    assert cls().task.id == newest
    assert doc.lstrip().startswith(f"`{newest}`")


GENERATED = {
    "docs/baselines.md": [
        "choices table",
        "baselines table",
        "marl table",
        "campaign table",
        "legged table",
        "steering table",
    ],
    "docs/tasks.md": [
        "reward calibration",
        "every task table",
        "pushrecovery-growth calibration",
        "team calibration",
        "mixed calibration",
        "leggedbumps-difficulty calibration",
        "leggedobstacles-difficulty calibration",
        "two robots table",
        "steering calibration",
        "waypointsbumps-difficulty calibration",
        "swap table",
        "convoyturns sentence",
        "rendezvous calibration",
        "bumps-difficulty calibration",
        "obstacles-difficulty calibration",
        "slopes-difficulty calibration",
    ],
}


@pytest.mark.parametrize("page", sorted(GENERATED))
def test_the_docs_tables_are_what_their_scripts_print_from_the_files(monkeypatch, page):
    from conftest import load_script

    check = load_script("check_docs")
    monkeypatch.chdir(Path(__file__).resolve().parents[1])
    assert [str(path) for path in check.DOCS] == sorted(GENERATED)
    found = check.blocks(Path(page).read_text())
    assert [m["name"] for m in found] == GENERATED[page]
    for match in found:
        assert check.printed(match["command"]) == match["body"], match["name"]
    tampered = found[2]["body"].replace("0.", "9.", 1)  # one figure of a table
    assert tampered != check.printed(found[2]["command"])


def _normalized_by_task(results: Path) -> dict[str, float]:
    document = json.loads(results.read_text())
    return {
        block["task"]: block["aggregate"]["normalized_score"]
        for block in document["tasks"]
        if block["aggregate"].get("normalized_score") is not None
    }


def recorded_seed_figures(root: Path) -> set[str]:
    """Every "a / b / c" the records give, at 3 decimals: the seeds of one recipe on one
    task in seed order (the board's runs, `leaderboards/results/<method>-s<seed>.json`,
    and the trainings kept off it, `baselines/<recipe>-s<seed>/results.json`), and one
    run's or controller's tasks in the order of its results document."""
    by_recipe: dict[str, dict[int, dict[str, float]]] = {}
    runs = [
        (f"board {path.name}", path)
        for path in (root / "leaderboards" / "results").glob("*.json")
        if not is_profile(path.name)
    ] + [(f"baselines {p.parent.name}", p) for p in (root / "baselines").glob("*/results.json")]
    shown: set[str] = set()
    for name, path in runs:
        scores = _normalized_by_task(path)
        shown.add(" / ".join(f"{value:.3f}" for value in scores.values()))
        stem = re.fullmatch(r"(.+)-s(\d+)(?:\.json)?", name)
        if stem:
            by_recipe.setdefault(stem[1], {})[int(stem[2])] = scores
    for by_seed in by_recipe.values():
        seeds = sorted(by_seed)
        for task in by_seed[seeds[0]]:
            values = [by_seed[seed].get(task) for seed in seeds]
            for n in range(2, len(values) + 1):
                if None not in values[:n]:
                    shown.add(" / ".join(f"{value:.3f}" for value in values[:n]))
    return shown


def test_the_per_seed_figures_in_the_notebook_are_the_records():
    """The notebook (docs/notebook.md) quotes seeds' scores as "a / b / c": each such run
    of figures must be what the records give, seed by seed."""
    root = Path(__file__).resolve().parents[1]
    text = (root / "docs" / "notebook.md").read_text()
    quoted = re.findall(r"-?\d\.\d{3}(?: / -?\d\.\d{3})+", text)
    assert len(quoted) >= 30  # the notebook quotes its seeds this way
    recorded = recorded_seed_figures(root)
    assert [figures for figures in quoted if figures not in recorded] == []
    # A figure typed wrong is found: one seed's score moved by 0.001.
    first = quoted[0]
    wrong = first[:4] + str((int(first[4]) + 1) % 10) + first[5:]
    assert wrong not in recorded


# A score as the board prints it (0.556, -0.440), or an interval of figures ([0.486,
# 0.619], [0.71, 0.83]); a range of integers ([-2, 2] m/s) is a task's parameter.
SCORE = re.compile(r"(?<![\w.`])-?\d\.\d{3}(?![\w.])|\[-?\d+\.\d+, -?\d+\.\d+\]")
VERDICTS = re.compile(r"^<!-- verdicts: .*?^<!-- verdicts: end -->$", re.MULTILINE | re.DOTALL)


def typed_scores(text: str, blocks) -> list[str]:
    """The scores and intervals of a page outside its generated blocks (and code)."""
    for block in reversed(blocks(text)):
        text = text[: block.start()] + text[block.end() :]
    text = VERDICTS.sub("", text)
    text = re.sub(r"`[^`\n]*`", "", text)
    return SCORE.findall(text)


@pytest.mark.parametrize("page", sorted(GENERATED))
def test_no_score_is_typed_by_hand_outside_the_generated_blocks(page):
    """Every score and interval docs/baselines.md and docs/tasks.md show is printed from the
    board or a record (the notebook keeps the pilots' figures as they were measured)."""
    from conftest import load_script

    blocks = load_script("check_docs").blocks
    text = (Path(__file__).resolve().parents[1] / page).read_text()
    assert typed_scores(text, blocks) == []
    # a score typed into the prose is found
    assert typed_scores(text + "\nPD scores 0.305 [0.266, 0.345].\n", blocks) == [
        "0.305",
        "[0.266, 0.345]",
    ]


def test_a_verdict_on_a_saturated_task_says_so():
    """docs/baselines.md's verdicts: a row on a task the board marks saturated (FlatBalance-v1
    today, where 0.999 against 1.000 is "below") says it is a check; no other row does."""
    import bbbench.leaderboard.verdicts as verdicts

    root = Path(__file__).resolve().parents[1]
    board = json.loads((root / "leaderboards" / "bbbench-v0.json").read_text())
    saturated = {
        task["task"].removeprefix("bbbench/")
        for track in board["tracks"]
        for task in track["tasks"]
        if task["saturated"]
    }
    assert "FlatBalance-v1" in saturated
    table = VERDICTS.search((root / "docs" / "baselines.md").read_text()).group()
    rows = [
        line.split(" | ")
        for line in table.splitlines()
        if line.startswith("| ") and "---" not in line
    ][1:]
    assert rows
    for row in rows:
        task, said = row[0].removeprefix("| "), row[-1]
        assert ("saturated" in said) == (task in saturated), row
    assert verdicts.verdict(0.0, 0.33, 3, saturated=True).startswith("below (a saturated")
    assert verdicts.verdict(0.4, 0.6, 1) == "not separated by 1 run"


def test_the_robots_page_names_each_robots_tasks():
    from bbbench.robots import ROBOTS
    from bbbench.tasks.suite import list_tasks, spec

    page = (Path(__file__).parents[1] / "docs" / "robots.md").read_text()
    rows = {
        cells[0].strip("`"): cells[1]
        for cells in (
            [cell.strip() for cell in line.strip().strip("|").split("|")]
            for line in page.split("| robot | tasks |")[1].split("\n\n")[0].splitlines()[2:]
        )
    }
    assert sorted(rows) == sorted(ROBOTS)
    for robot, listed in rows.items():
        names = {t.name for t in map(spec, list_tasks()) if robot in (t.robots or (t.robot,))}
        assert set(listed.split(", ")) == names, robot

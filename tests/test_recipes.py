"""docs/architecture.md's "How to add..." followed as written: a throwaway robot and a
throwaway scenario, each made by the recipe's steps alone, play, pass Gymnasium's or
PettingZoo's checker, are scored by `evaluate()` and listed by `list_tasks()`."""

from __future__ import annotations

import dataclasses
import re
import shutil
from pathlib import Path

import gymnasium
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test

import bbbench
from bbbench.evaluation import evaluate
from bbbench.policies import classical_controller, load_policy
from bbbench.robots import ROBOTS, TWO_WHEEL
from bbbench.robots.balancebot import URDF_PATH, BalanceBot, read_model
from bbbench.robots.robot import registered
from bbbench.robots.twowheel import TwoWheel
from bbbench.tasks.scenario import SCENARIOS, register_scenario
from bbbench.tasks.scenarios import Crossing
from bbbench.tasks.suite import SUITE, list_tasks, register_suite
from bbbench.tasks.tracks import TRACKS, Track, track_of

ROOT = Path(__file__).resolve().parents[1]
RECIPES = (ROOT / "docs" / "architecture.md").read_text()


def recipe(name: str) -> str:
    """The recipe "A <name>." of docs/architecture.md's "How to add..."."""
    start = RECIPES.index(f"- **{name}.**")
    end = RECIPES.find("\n- **", start + 1)
    return RECIPES[start : end if end > 0 else RECIPES.index("\n## ", start)]


@pytest.fixture
def in_the_suite(monkeypatch):
    """Put task rows in the suite and gymnasium's registry for the test, as a scenario
    module's `TASKS` does, and take them out after."""
    added = []

    def add(row) -> str:
        monkeypatch.setitem(SUITE, row.id, row)
        register_suite()
        added.append(row.id)
        return row.id

    yield add
    for task_id in added:
        gymnasium.registry.pop(task_id, None)


def test_a_robot_made_by_the_recipe_plays_is_checked_scored_and_listed(
    tmp_path, monkeypatch, in_the_suite
):
    steps = recipe("A robot")
    # 1. A URDF, and its facts read from it.
    urdf = tmp_path / "probebot.urdf"
    shutil.copy(URDF_PATH, urdf)
    model = read_model(urdf)

    # 2. A body class on `Body`: here the two-wheel bot's, on the new URDF's facts.
    class ProbeBody(BalanceBot):
        def __init__(self, client) -> None:
            super().__init__(client, model)

    # 3. A `Robot` that declares its parts and writes its methods (the two-wheel bot's).
    class Probe(TwoWheel):
        name = "probe"
        summary = "a throwaway robot: the two-wheel bot's body under another name"
        controller = "random"

        def body(self, client) -> ProbeBody:
            return ProbeBody(client)

    Probe.model = model
    # 4. Registered in `ROBOTS` (bbbench/robots/__init__.py's `registered`).
    (probe,) = registered([Probe()]).values()
    monkeypatch.setitem(ROBOTS, "probe", probe)
    # 5. A task row naming it, in a scenario module's `TASKS`.
    row = dataclasses.replace(
        SUITE["bbbench/FlatBalance-v1"], id="bbbench/ProbeFlat-v0", robot="probe",
        random_return=None, version_history=("v0: initial release.",),
    )  # fmt: skip
    task_id = in_the_suite(row)
    # 6. A track that ranks its tasks (bbbench/tasks/tracks.py).
    track = Track("probe", "probe", "the probe robot's tasks", "probe", False, task_id)
    monkeypatch.setitem(TRACKS, "probe", track)
    for named in ("ROBOTS", "registered", "bbbench/robots/__init__.py", "bbbench/tasks/tracks.py"):
        assert named in steps, named

    env = gymnasium.make(task_id)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()
    assert task_id in list_tasks()
    assert track_of(bbbench.spec(task_id)) is track
    assert classical_controller(task_id) == "random"
    document = evaluate(load_policy("random"), [task_id], episodes=2, workers=1).document
    assert [block["task"] for block in document["tasks"]] == [task_id]
    assert len(document["tasks"][0]["episodes"]) == 2
    assert load_policy("pd").mismatch(task_id)  # PD controls the two-wheel robot only
    assert TWO_WHEEL.name != probe.name


def test_a_scenario_made_by_the_recipe_plays_is_checked_scored_and_listed(
    monkeypatch, in_the_suite
):
    steps = recipe("A scenario")

    # 1. A class on `Scenario`, registered: here the crossings' rules under a new name,
    # each bot's info carrying one metric more.
    class Huddle(Crossing):
        name = "huddle"
        summary = "a throwaway scenario: the crossings, with the spread of the group"
        metrics = ("velocity_error", "spread")

        def outcome(self, agents, states, targets, seed):
            outcome = super().outcome(agents, states, targets, seed)
            xs = [state.axle[0] for state in states]
            for info in outcome.infos:
                info["spread"] = max(xs) - min(xs)
            return outcome

    monkeypatch.setitem(SCENARIOS, "huddle", Huddle)
    SCENARIOS.pop("huddle")
    register_scenario(Huddle)  # what `@register_scenario` does
    # 2. Its tasks' rows, with `scenario="huddle"`.
    row = dataclasses.replace(
        SUITE["bbbench/MultiBalance-v1"], id="bbbench/Huddle-v0", scenario="huddle",
        random_return=None, version_history=("v0: initial release.",),
    )  # fmt: skip
    task_id = in_the_suite(row)
    for named in ("register_scenario", "MODULES", "TASKS", "observe_and_score"):
        assert named in steps, named

    parallel_api_test(bbbench.make_parallel(task_id), num_cycles=50)
    assert task_id in list_tasks(multi_agent=True)
    assert classical_controller(task_id) == "pd"  # its robot's: it names none
    document = evaluate(load_policy("pd"), [task_id], episodes=2, workers=1).document
    (block,) = document["tasks"]
    assert block["task"] == task_id
    assert all(re.fullmatch(r"[\d.e-]+", str(e["spread"])) for e in block["episodes"])

"""docs/architecture.md's recipes hold: every file they name exists, a task's row sits
beside its scenario, and adding a task touches nothing of the MARL or training code."""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

import bbbench
from bbbench.tasks.scenario import SCENARIOS
from bbbench.tasks.scenarios import MODULES, TASKS
from bbbench.tasks.suite import SUITE

ROOT = Path(__file__).resolve().parents[1]
RECIPES = ROOT / "docs" / "architecture.md"
TASK_ID = re.compile(r"bbbench/[A-Z][A-Za-z]+-v\d+")


def recipes() -> str:
    text = RECIPES.read_text()
    return text[text.index("## How to add...") : text.index("## One episode, written once")]


def named_files(text: str) -> set[str]:
    """The repository files a text names in backticks (`bbbench/tasks/scenario.py`)."""
    found = re.findall(r"`((?:bbbench|tests|docs|benchmarks|scripts)/[\w/.<>*-]+)`", text)
    return {path for path in found if "<" not in path and "*" not in path}


def test_every_file_the_recipes_name_exists():
    named = named_files(recipes())
    assert len(named) > 15  # the reading finds them
    assert sorted(path for path in named if not (ROOT / path).exists()) == []


def test_the_reading_of_named_files_sees_a_missing_one():
    assert named_files("a `bbbench/tasks/nope.py` and `bbbench/tasks/<x>.py`") == {
        "bbbench/tasks/nope.py"
    }


def test_each_task_row_is_in_its_scenarios_module():
    assert {task.id for task in TASKS} == set(SUITE)
    for task in SUITE.values():
        module = sys.modules[SCENARIOS[task.scenario].__module__]
        assert module in MODULES, task.id
        assert task in module.TASKS, f"{task.id} is not beside its scenario, {module.__name__}"


def code_naming_a_task(path: Path, root: Path = ROOT) -> list[str]:
    """Where a module's code (not its docstrings) names a task ID."""
    tree = ast.parse(path.read_text())
    docstrings = {
        id(node.body[0].value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef)
        and node.body
        and isinstance(node.body[0], ast.Expr)
        and isinstance(node.body[0].value, ast.Constant)
    }
    return [
        f"{path.relative_to(root)}:{node.lineno}: {node.value!r}"
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant)
        and isinstance(node.value, str)
        and id(node) not in docstrings
        and TASK_ID.search(node.value)
    ]


def test_no_marl_or_training_code_names_a_task():
    """A task is its row (and its generated artefacts): its BenchMARL task, configuration
    and default recipe come from the suite, so no code there names one."""
    found = [
        where
        for folder in ("marl", "training")
        for path in sorted((ROOT / "bbbench" / folder).rglob("*.py"))
        for where in code_naming_a_task(path)
    ]
    assert found == []


def test_the_reading_of_task_ids_sees_one_in_code(tmp_path):
    module = tmp_path / "probe.py"
    module.write_text('"""About bbbench/FlatBalance-v1."""\nTASK = "bbbench/FlatBalance-v1"\n')
    assert code_naming_a_task(module, tmp_path) == ["probe.py:2: 'bbbench/FlatBalance-v1'"]


def comparisons_of_a_name(path: Path, names: set[str], root: Path = ROOT) -> list[str]:
    """Where `path` compares something with a scenario's or robot's name (==, !=, in):
    a special case kept outside the scenario or robot it is about."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return [
        f"{path.relative_to(root)}:{node.lineno}: {ast.unparse(node)}"
        for node in ast.walk(tree)
        if isinstance(node, ast.Compare)
        and any(isinstance(op, (ast.Eq, ast.NotEq, ast.In, ast.NotIn)) for op in node.ops)
        and any(
            isinstance(side, ast.Constant) and side.value in names
            for side in (node.left, *node.comparators)
        )
    ]


def test_no_code_outside_a_scenario_or_robot_compares_its_name():
    """A scenario declares its classical controller and what a steering bot heads for; a
    robot its controller and its task classes' interface: no code elsewhere, in the
    package or its scripts, keys a special case on their names."""
    from bbbench.robots import ROBOTS

    names = set(SCENARIOS) | set(ROBOTS)
    owners = (ROOT / "bbbench" / "tasks" / "scenarios", ROOT / "bbbench" / "robots")
    found = [
        where
        for folder in (ROOT / "bbbench", ROOT / "scripts")
        for path in sorted(folder.rglob("*.py"))
        if not any(path.is_relative_to(owner) for owner in owners)
        for where in comparisons_of_a_name(path, names)
    ]
    assert found == []


def test_the_reading_of_comparisons_sees_one(tmp_path):
    module = tmp_path / "probe.py"
    module.write_text('def f(task):\n    return task.scenario == "swap" or "x" in "xy"\n')
    assert comparisons_of_a_name(module, {"swap"}, tmp_path) == [
        "probe.py:2: task.scenario == 'swap'"
    ]


def test_the_recipes_name_the_scenarios_registry_and_rows():
    text = recipes()
    for name in ("register_scenario", "MODULES", "TASKS", "bbbench/tasks/scenarios/__init__.py"):
        assert name in text
    assert bbbench.spec("bbbench/BeamCarry-v0").coupling.__module__.endswith("beam_carry")


def test_the_multi_bot_env_is_a_thin_layer():
    """MultiBalanceEnv maps the scenario's outcome to PettingZoo's API and decides
    nothing: at most 150 lines besides its docstring (the issue that thinned it)."""
    path = ROOT / "bbbench" / "envs" / "multi.py"
    (env,) = (
        node
        for node in ast.parse(path.read_text()).body
        if isinstance(node, ast.ClassDef) and node.name == "MultiBalanceEnv"
    )
    docstring = env.body[0]
    lines = env.end_lineno - env.lineno + 1
    assert lines - (docstring.end_lineno - docstring.lineno + 1) <= 150


def the_map() -> str:
    """docs/architecture.md's map: "The layers, one sentence per module"."""
    return RECIPES.read_text().split("## The layers")[1].split("\n## ")[0]


def test_the_map_names_every_module_and_package_and_nothing_else():
    text = the_map()
    package = ROOT / "bbbench"
    modules = [p.relative_to(package) for p in sorted(package.rglob("*.py"))]
    unnamed = [
        str(module)
        for module in modules
        if module.name != "__init__.py"
        and f"`{module.name}`" not in text
        and module.as_posix() not in text
    ]
    assert unnamed == [], "name these in docs/architecture.md's map"
    folders = sorted({module.parent for module in modules if module.parent != Path(".")})
    assert [
        f for f in folders if f"{f.as_posix()}/" not in text and f"`{f.name}/`" not in text
    ] == []
    named = set(re.findall(r"`([\w/]+\.py)`", text))
    paths = [f"bbbench/{module.as_posix()}" for module in modules]
    assert [n for n in named if not any(path.endswith(n) for path in paths)] == []

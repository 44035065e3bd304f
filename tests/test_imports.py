"""The package imports one way: no module imports, directly or through others, a module
that imports it back (function-level imports included, so none can hide a cycle)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import bbbench

PACKAGE = Path(__file__).resolve().parents[1] / "bbbench"


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules() -> dict[str, Path]:
    return {module_name(path): path for path in sorted(PACKAGE.rglob("*.py"))}


def imports_of(path: Path, known: set[str]) -> set[str]:
    """The package's modules `path` imports, anywhere in it: `from a.b import c` is a.b.c
    when that is a module, else a.b."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the package, up level - 1
                parent = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*parent, *([base] if base else [])])
            targets = [f"{base}.{alias.name}" for alias in node.names] + [base]
            targets = [t for t in targets if t in known][:1] or [base]
        else:
            continue
        found.update(t for t in targets if t in known and t != name)
    return found


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of `graph` as a list of modules (first repeated last), or None."""
    state: dict[str, int] = {}  # 1: on the path being explored, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for following in sorted(graph[node]):
            if state.get(following) == 1:
                return [*path[path.index(following) :], following]
            if following not in state and (cycle := visit(following)):
                return cycle
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return None


def import_graph() -> dict[str, set[str]]:
    found = modules()
    return {name: imports_of(path, set(found)) for name, path in found.items()}


def test_the_package_has_no_import_cycle():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_the_graph_sees_the_imports_it_checks():
    """The test would see a cycle: its reading of imports finds the known edges."""
    graph = import_graph()
    assert "bbbench.tasks.spec" in graph["bbbench.tasks.suite"]
    assert "bbbench.envs.scene" in graph["bbbench.envs.balance"]
    assert "bbbench.envs.factory" in graph["bbbench.envs"]  # an __init__
    # A function-level import counts too (lqr identifies its model on a made env).
    assert "bbbench.envs.factory" in graph["bbbench.policies.lqr"]


@pytest.mark.parametrize(
    ("graph", "expected"),
    [
        ({"a": {"b"}, "b": {"c"}, "c": set()}, None),
        ({"a": {"b"}, "b": {"c"}, "c": {"a"}}, ["a", "b", "c", "a"]),
        ({"a": {"a"}}, ["a", "a"]),
    ],
)
def test_find_cycle(graph, expected):
    assert find_cycle(graph) == expected


def test_spec_and_suite_import_no_env_code():
    """The data side (specs, the task table) stands below the envs."""
    graph = import_graph()
    envs = {name for name in graph if name.startswith("bbbench.envs")}
    envs.add("bbbench.dev.golden")
    assert "bbbench.envs.tasks" in envs

    def reachable(start: str) -> set[str]:
        seen, todo = set(), [start]
        while todo:
            for following in graph[todo.pop()] - seen:
                seen.add(following)
                todo.append(following)
        return seen

    for data in ("bbbench.tasks.spec", "bbbench.tasks.suite"):
        assert not reachable(data) & envs, data


def function_level_imports() -> list[tuple[str, int, str, str]]:
    """(file, line, the line, the line above) of every import inside a function."""
    found = []
    for path in sorted(Path(bbbench.__file__).parent.rglob("*.py")):
        lines = path.read_text().splitlines()
        stack = [(ast.parse("\n".join(lines)), False)]
        while stack:
            node, in_function = stack.pop()
            for child in ast.iter_child_nodes(node):
                if isinstance(child, ast.Import | ast.ImportFrom):
                    if in_function:
                        row = child.lineno - 1
                        found.append((path.name, child.lineno, lines[row], lines[row - 1]))
                else:
                    function = isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef)
                    stack.append((child, in_function or function))
    return found


def test_every_function_level_import_says_why_it_is_lazy_and_the_count_is_documented():
    """Imports inside functions only keep a command or an optional dependency lazy."""
    found = function_level_imports()
    unexplained = [
        f"{name}:{line}: {text.strip()}"
        for name, line, text, above in found
        if "# lazy:" not in text and "# lazy:" not in above
    ]
    assert unexplained == [], "a function-level import without '# lazy: why'"
    architecture = (Path(__file__).parents[1] / "docs" / "architecture.md").read_text()
    assert f"There are {len(found)} in `bbbench/`" in architecture

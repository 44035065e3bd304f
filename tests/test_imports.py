"""The package imports one way: no module imports, directly or through others, a module
that imports it back (function-level imports included, so none can hide a cycle)."""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

import pytest

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
    assert "bbbench.envs.factory" in graph["bbbench.policies.controllers.lqr"]


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


def reachable(graph: dict[str, set[str]], start: str) -> set[str]:
    """Every module `start` imports, directly or through others."""
    seen, todo = set(), [start]
    while todo:
        for following in graph[todo.pop()] - seen:
            seen.add(following)
            todo.append(following)
    return seen


def test_spec_and_suite_import_no_env_code():
    """The data side (specs, the task table) stands below the envs."""
    graph = import_graph()
    envs = {name for name in graph if name.startswith("bbbench.envs")}
    envs.add("bbbench.dev.golden")
    assert "bbbench.envs.task_envs" in envs

    for data in ("bbbench.tasks.spec", "bbbench.tasks.suite"):
        assert not reachable(graph, data) & envs, data


POLICY_FORMATS = ("bbbench.policies.sb3", "bbbench.policies.onnx")
POLICY_BASE = (
    "bbbench.policies.policy",
    "bbbench.policies.file_policy",
    "bbbench.policies.archive",
    "bbbench.policies.mlp",
    "bbbench.policies.normalization",
    "bbbench.policies.encoder",
    "bbbench.policies.errors",
)


def test_the_policies_base_knows_no_file_format_and_the_formats_not_each_other():
    graph = import_graph()
    # The junction above them reaches every kind (so the test sees these edges).
    assert {"bbbench.policies.sb3.policy", "bbbench.policies.onnx.policy"} <= reachable(
        graph, "bbbench.policies.registry"
    )
    kinds = (*POLICY_FORMATS, "bbbench.policies.controllers")
    for base in POLICY_BASE:
        assert not {m for m in reachable(graph, base) if m.startswith(kinds)}, base
    for one, other in (POLICY_FORMATS, POLICY_FORMATS[::-1]):
        for module in (m for m in graph if m.startswith(one)):
            assert not {m for m in reachable(graph, module) if m.startswith(other)}, module


def test_marl_imports_nothing_of_training():
    """Training sits above the TorchRL face of the envs (`bbbench.marl`), never below."""
    graph = import_graph()
    for module in (m for m in graph if m.startswith("bbbench.marl")):
        assert not {m for m in reachable(graph, module) if m.startswith("bbbench.training")}


def function_level_imports() -> list[tuple[str, int, str, str]]:
    """(file, line, imported module, its '# lazy:' comment, on its line or the one above)
    of every import inside a function."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        lines = path.read_text().splitlines()
        stack = [(ast.parse("\n".join(lines)), False)]
        while stack:
            node, in_function = stack.pop()
            for child in ast.iter_child_nodes(node):
                if isinstance(child, ast.Import | ast.ImportFrom):
                    if in_function:
                        row = child.lineno - 1
                        comment = lines[row] if "# lazy:" in lines[row] else lines[row - 1]
                        found.append((path.name, child.lineno, imported(child), comment))
                else:
                    function = isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef)
                    stack.append((child, in_function or function))
    return found


def imported(node: ast.Import | ast.ImportFrom) -> str:
    """The module an import statement loads: `from bbbench import evaluation` loads
    bbbench.evaluation."""
    if isinstance(node, ast.Import):
        return node.names[0].name
    module = node.module or ""
    submodule = f"{module}.{node.names[0].name}"
    return (
        submodule
        if importlib.util.find_spec(module).submodule_search_locations
        and (importlib.util.find_spec(submodule) is not None)
        else module
    )


def lazy_module(comment: str) -> str | None:
    """The module a '# lazy: MODULE, why' comment names (None: no such comment)."""
    if "# lazy:" not in comment:
        return None
    return comment.split("# lazy:", 1)[1].strip().split(",")[0].split()[0]


def test_every_function_level_import_names_the_module_it_keeps_lazy():
    """An import inside a function keeps a command's subsystem or a heavy dependency from
    loading until it is used, and its comment names which: '# lazy: MODULE[, why]', where
    MODULE is the module imported (or a package holding it), or a third-party module it
    loads (torch, matplotlib, ...). Any number of them may be added; none unmarked."""
    wrong = []
    for name, line, module, comment in function_level_imports():
        named = lazy_module(comment)
        if named is None:
            wrong.append(f"{name}:{line}: import of {module} without '# lazy: MODULE'")
            continue
        ours = named == "bbbench" or named.startswith("bbbench.")
        if ours and not (module == named or module.startswith(named + ".")):
            wrong.append(f"{name}:{line}: '# lazy: {named}' does not hold {module}")
        elif not ours and importlib.util.find_spec(named) is None:
            wrong.append(f"{name}:{line}: '# lazy: {named}' is not a module")
    assert wrong == []


def test_the_lazy_rule_catches_an_unmarked_or_misnamed_import():
    assert lazy_module("    import torch") is None
    assert lazy_module("    import torch  # lazy: torch, for policy files only") == "torch"
    assert lazy_module("    # lazy: stable_baselines3") == "stable_baselines3"
    found = {
        (name, module): lazy_module(comment)
        for name, _, module, comment in function_level_imports()
    }
    assert found[("rebuild.py", "torch")] == "torch"
    assert found[("train.py", "bbbench.training")] == "bbbench.training"

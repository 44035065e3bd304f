"""The recipe files shipped in the package (`bbbench/training/recipes/<algorithm>.yml`),
read as data: rl-zoo3's format for stable-baselines3 (`bbbench.training.sb3.recipes`),
BenchMARL's config groups for IPPO and MAPPO (`bbbench.training.benchmarl.recipes`)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

import yaml


def recipe_file(algorithm: str):
    """The recipe file of `algorithm` ("ppo"; a path inside the installed package)."""
    return resources.files("bbbench.training") / "recipes" / f"{algorithm}.yml"


def read_recipe_file(algorithm: str, file: str | Path | None = None) -> dict[str, Any]:
    """A recipe file's table (task ID -> recipe): `file`, or `algorithm`'s shipped one."""
    source = Path(file) if file is not None else recipe_file(algorithm)
    try:
        table = yaml.safe_load(source.read_text())
    except OSError as error:
        raise ValueError(f"recipe file {source}: {error}") from None
    except yaml.YAMLError as error:  # one line: where, and what
        mark = getattr(error, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(error, "problem", None) or str(error).splitlines()[0]
        raise ValueError(
            f"recipe file {source}: not valid YAML{where}: {problem}; fix it, or copy the "
            f"shipped {algorithm}.yml and change it"
        ) from None
    if not isinstance(table, dict):
        raise ValueError(f"recipe file {source}: expected task IDs, each with its recipe")
    return table

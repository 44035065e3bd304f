"""BenchMARL's hydra CLI on bbbench's tasks.

    python -m bbbench.marl.run algorithm=mappo task=bbbench/beamcarry_v0 seed=0
    python -m bbbench.marl.run -m algorithm=ippo,mappo task=bbbench/multibalance_v1 seed=0,1,2

is `benchmarl/run.py` (the same config groups and overrides: `experiment.*`,
`model=layers/...`, `task.n_bots=...`) with bbbench's tasks registered and their
YAML on hydra's search path.
"""

from __future__ import annotations

import sys

from benchmarl.run import hydra_experiment

import bbbench.marl  # noqa: F401 (registers bbbench's tasks with BenchMARL)

SEARCH_PATH = "hydra.searchpath=[pkg://bbbench.marl.conf]"


def main() -> None:
    if not any(arg.startswith("hydra.searchpath") for arg in sys.argv[1:]):
        sys.argv.append(SEARCH_PATH)
    hydra_experiment()


if __name__ == "__main__":
    main()

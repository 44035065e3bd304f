"""BenchMARL's hydra CLI on bbbench's tasks.

    python -m bbbench.marl.run algorithm=mappo task=bbbench/beamcarry_v0 seed=0
    python -m bbbench.marl.run -m algorithm=ippo,mappo task=bbbench/multibalance_v1 seed=0,1,2

is `benchmarl/run.py` (the same config groups and overrides: `experiment.*`,
`model=layers/...`, `task.n_bots=...`) with bbbench's tasks registered, and each task's
config made from its row of the suite (`store_task_configs`), where BenchMARL's own
tasks have a YAML file: in hydra's config store, as `task/bbbench/<name>`.
"""

from __future__ import annotations

from benchmarl.run import hydra_experiment
from hydra.core.config_store import ConfigStore

from bbbench.marl.family import ENV_NAME, BbbenchTask, task_config, task_id


def store_task_configs() -> None:
    """Put every member of `BbbenchTask`'s configuration in hydra's config store, where
    `task=bbbench/<name>` finds it (as it would find `conf/task/bbbench/<name>.yaml`)."""
    store = ConfigStore.instance()
    for member in BbbenchTask:
        config = task_config(task_id(member.name))
        store.store(group=f"task/{ENV_NAME}", name=member.name.lower(), node=config)


def main() -> None:
    store_task_configs()
    hydra_experiment()


if __name__ == "__main__":
    main()

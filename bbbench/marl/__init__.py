"""Multi-agent learning on bbbench's multi-bot and team tasks, with BenchMARL (TorchRL).

    pip install 'bbbench[marl]'

    from benchmarl.algorithms import MappoConfig
    from benchmarl.experiment import Experiment, ExperimentConfig
    from benchmarl.models import MlpConfig
    from bbbench.marl import BbbenchTask

    Experiment(
        task=BbbenchTask.BEAMCARRY_V0.get_from_yaml(),
        algorithm_config=MappoConfig.get_from_yaml(),
        model_config=MlpConfig.get_from_yaml(),
        critic_model_config=MlpConfig.get_from_yaml(),
        seed=0,
        config=ExperimentConfig.get_from_yaml(),
    ).run()

`bbbench.marl.batched_env(task_id, worlds=K)` is K worlds of a task as one TorchRL env
of `batch_size=[K]` (what the family collects from). `bbbench.marl.family` holds the
task family; importing it registers the tasks in
BenchMARL's registry (`benchmarl.environments.task_config_registry`), under
`bbbench/<task>` (`bbbench/multibalance_v1`, ...).
"""

from bbbench.marl.batched import BatchedTorchEnv, batched_env
from bbbench.marl.family import BbbenchTask, BbbenchTaskClass

__all__ = ["BatchedTorchEnv", "BbbenchTask", "BbbenchTaskClass", "batched_env"]

"""The BenchMARL route's recipes: `bbbench/training/recipes/{ippo,mappo}.yml`, one entry
per task ID, beside the stable-baselines3 recipes.

An entry's sections override BenchMARL's own YAML of each config group: `task` (the
task's configuration, from its row: `bbbench.marl.family.task_config`), `algorithm`
(BenchMARL's `conf/algorithm/<algo>.yaml`, here its masked version:
`bbbench.marl.algorithms`), `model` and `critic_model` (`name: mlp`, BenchMARL's
`conf/model/layers/mlp.yaml`, or `name: neighbour_encoder`, `bbbench.marl.models`; the
actor of a recurrent method, `ippo-gru` or `mappo-gru`, `name: gru`, BenchMARL's
`conf/model/layers/gru.yaml`, one layer, exported with its state:
`bbbench.marl.models.RecurrentActor`) and `experiment` (BenchMARL's
`conf/experiment/base_experiment.yaml`). One section is bbbench's own: `segments`
(`frames`: train in segments of that many world steps, a training that resumes where it
was stopped: `bbbench.training.benchmarl.segments`; without it, one segment). Every key
is checked against the fields of BenchMARL's config classes; what `bbbench train` owns
(devices, action type, evaluation, loggers, checkpoints) is refused, as is an entropy
bonus (it would reach the policy through a fallen bot's rows).
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path
from typing import Any

import torch
import torch.nn
from benchmarl.experiment import Experiment, ExperimentConfig
from benchmarl.models import GruConfig, MlpConfig

import bbbench
from bbbench.envs.batched import check_memory
from bbbench.marl.family import task_class, task_config
from bbbench.marl.models import NeighbourEncoderConfig
from bbbench.policies.sb3.algorithms import unknown
from bbbench.tasks.suite import latest_version
from bbbench.training.algorithms import MARL_TRAINABLE, trainable
from bbbench.training.benchmarl.segments import check_segments
from bbbench.training.recipe_files import read_recipe_file

MODELS = ("mlp", "neighbour_encoder", "gru")
# What of BenchMARL's GRU model a recipe may set: one layer, no dropout, uncompiled (the
# board's recurrent contract carries one GRU cell; `torch.compile` changes no result).
_GRU_FIELDS = ("hidden_size", "bias", "mlp_num_cells", "mlp_activation_class")
SECTIONS = ("task", "algorithm", "model", "critic_model", "experiment", "segments")
# What bbbench train sets itself (the key, and why).
OWNED = {
    "sampling_device": "training runs on the CPU",
    "train_device": "training runs on the CPU",
    "buffer_device": "training runs on the CPU",
    "share_policy_params": "one policy is shared by every bot (the board scores one)",
    "evaluation": "bbbench evaluates on training seeds itself",
    "evaluation_interval": "bbbench evaluates on training seeds itself",
    "evaluation_episodes": "bbbench evaluates on training seeds itself",
    "evaluation_deterministic_actions": "bbbench evaluates on training seeds itself",
    "evaluation_static": "bbbench evaluates on training seeds itself",
    "render": "bbbench train renders nothing",
    "loggers": "bbbench train writes its own curve",
    "project_name": "bbbench train writes its own curve",
    "wandb_extra_kwargs": "bbbench train writes its own curve",
    "create_json": "bbbench train writes its own curve",
    "save_folder": "bbbench train writes where --out says",
    "restore_file": "bbbench train resumes a training itself (a recipe's segments)",
    "restore_map_location": "bbbench train resumes a training itself (a recipe's segments)",
    "checkpoint_interval": "bbbench train keeps the policy itself (the last one)",
    "checkpoint_at_end": "bbbench train keeps the policy itself (the last one)",
    "keep_checkpoints_num": "bbbench train keeps the policy itself (the last one)",
    "exclude_buffer_from_checkpoint": "bbbench train keeps the policy itself (the last one)",
    "max_n_iters": "the budget is max_n_frames (or --steps)",
}
_ACTIVATIONS = ("Tanh", "ReLU", "LeakyReLU", "ELU", "Sigmoid")  # the ONNX reader runs these


# Torch threads of a training's updates (the advantages and the minibatch passes). While
# they run, the worker processes that step the worlds wait, so their cores are free;
# collection stays on one thread, beside the workers. A fixed count, not the machine's,
# so that a call writes the same bytes on every machine of one kind.
UPDATE_THREADS = 2


class PhasedExperiment(Experiment):
    """BenchMARL's `Experiment`, its updates on `UPDATE_THREADS` torch threads and its
    collection on one: from the batch collected to the last group's training end."""

    def _on_batch_collected(self, batch) -> None:
        super()._on_batch_collected(batch)
        torch.set_num_threads(UPDATE_THREADS)

    def _on_train_end(self, training_td, group: str) -> None:
        if group == list(self.train_group_map)[-1]:
            torch.set_num_threads(1)
        super()._on_train_end(training_td, group)


@dataclasses.dataclass(frozen=True)
class MarlRecipe:
    """How BenchMARL trains `algorithm` on the multi-bot task `key`: each section as the
    recipe overrides BenchMARL's own YAML of its group."""

    algorithm: str
    key: str
    task: dict[str, Any]
    algorithm_overrides: dict[str, Any]
    model: dict[str, Any]
    critic_model: dict[str, Any]
    experiment: dict[str, Any]
    segments: dict[str, Any] = dataclasses.field(default_factory=dict)
    normalize = None  # no VecNormalize: the BenchMARL route fixes a normalizer first

    @functools.cached_property
    def n_timesteps(self) -> int:
        """The default budget, in world steps (BenchMARL's frames)."""
        return int(
            self.experiment.get("max_n_frames", ExperimentConfig.get_from_yaml().max_n_frames)
        )

    @property
    def n_envs(self) -> int:
        """Worlds collected at once (one batched env of them)."""
        return int(self.experiment.get("on_policy_n_envs_per_worker", 1))

    @property
    def action_mode(self) -> str:
        """The actions the bots learn: continuous where the recipe's experiment prefers
        them (BenchMARL's `prefer_continuous_actions`) and on a mixed team, whose robots
        share no other mode; discrete otherwise."""
        if bbbench.spec(self.key).mixed or self.experiment.get("prefer_continuous_actions"):
            return "continuous"
        return "discrete"

    @property
    def segment_frames(self) -> int | None:
        """World steps of a segment of the training (None: one segment, the budget)."""
        return self.segments.get("frames")

    def batch(self) -> int:
        """World steps collected before each update (BenchMARL's frames per batch)."""
        return int(
            self.experiment.get(
                "on_policy_collected_frames_per_batch",
                ExperimentConfig.get_from_yaml().on_policy_collected_frames_per_batch,
            )
        )

    def batch_of(self, tasks, worlds: int, workers: int | None) -> int:
        """World steps a batch of `worlds` worlds stepped in `workers` processes collects
        (`bbbench.training.checks.check_collection`); `ValueError` if they do not fit."""
        check_memory(worlds)
        self.check_worlds(worlds)
        if workers is not None:
            check_workers(workers, worlds)
        return self.batch()

    def check_worlds(self, worlds: int) -> None:
        """`ValueError` unless a batch holds at least one world step of each of `worlds`."""
        if self.batch() < worlds:
            raise ValueError(
                f"{self.algorithm} recipe for {self.key}: a batch of {self.batch():,} world "
                f"steps from {worlds} worlds is less than one step per world: collect at "
                f"least {worlds} world steps a batch (on_policy_collected_frames_per_batch), "
                f"or fewer worlds"
            )

    def record(self) -> dict[str, Any]:
        """As `train.json` records it: the recipe's sections as written."""
        return {
            "algorithm": self.algorithm,
            "recipe": self.key,
            "trainer": "BenchMARL",
            "task": self.task,
            "algorithm_config": self.algorithm_overrides,
            "model": self.model,
            "critic_model": self.critic_model,
            "experiment": self.experiment,
            **({"segments": self.segments} if self.segments else {}),
        }

    def task_config(self):
        """The BenchMARL task: its configuration from the suite, with the recipe's."""
        return task_class(self.key, **self.task)

    def algorithm_config(self):
        config = trainable(self.algorithm).config_class().get_from_yaml()
        return dataclasses.replace(config, **self.algorithm_overrides)

    def model_config(self, critic: bool = False):
        section = self.critic_model if critic else self.model
        fields = {k: v for k, v in section.items() if k != "name"}
        if section["name"] == "neighbour_encoder":
            if "hidden" in fields:
                fields["hidden"] = tuple(fields["hidden"])
            return NeighbourEncoderConfig.for_task(self.key, **fields)
        if section["name"] == "gru":
            if "mlp_activation_class" in fields:
                fields["mlp_activation_class"] = _torch_class(fields["mlp_activation_class"])
            return dataclasses.replace(GruConfig.get_from_yaml(), **fields)
        for key in ("activation_class", "layer_class", "norm_class"):
            if fields.get(key) is not None:
                fields[key] = _torch_class(fields[key])
        return dataclasses.replace(MlpConfig.get_from_yaml(), **fields)

    def build_experiment(
        self, task, seed: int, frames: int, n_envs: int, folder: Path, callbacks=()
    ) -> Experiment:
        """BenchMARL's `Experiment` of this recipe on `task` (`task_config()`'s, perhaps
        changed): `frames` world steps from `n_envs` worlds, writing under `folder`."""
        return PhasedExperiment(
            task=task,
            algorithm_config=self.algorithm_config(),
            model_config=self.model_config(),
            critic_model_config=self.model_config(critic=True),
            seed=seed,
            config=self.experiment_config(frames, n_envs, folder),
            callbacks=list(callbacks),
        )

    def experiment_config(self, frames: int, n_envs: int, folder: Path) -> ExperimentConfig:
        config = ExperimentConfig.get_from_yaml()
        for key, value in self.experiment.items():
            setattr(config, key, value)
        config.sampling_device = config.train_device = config.buffer_device = "cpu"
        config.prefer_continuous_actions = self.action_mode == "continuous"
        config.share_policy_params = True
        config.max_n_frames = frames
        config.max_n_iters = None
        config.on_policy_n_envs_per_worker = n_envs
        config.evaluation = config.render = config.create_json = False
        config.loggers = []
        config.checkpoint_interval = 0
        config.checkpoint_at_end = False
        config.save_folder = str(folder)
        return config


def marl_recipe(algorithm: str, key: str, file: str | Path | None = None) -> MarlRecipe:
    """`algorithm`'s recipe for the multi-bot task `key`; `ValueError` saying what is wrong."""
    table = read_recipe_file(algorithm, file)
    where = f"{Path(file).name if file else f'{algorithm}.yml'}, {key}"
    if key not in table:
        like = _like(key, table)
        if like is None:
            named = Path(file).name if file else f"{algorithm}.yml"
            raise ValueError(
                f"no {algorithm} recipe for {key}; {named} has recipes for "
                f"{', '.join(map(str, table))}"
            )
        where = f"{where} (as {like})"
        entry = table[like]
    else:
        entry = table[key]
    if not isinstance(entry, dict):
        raise ValueError(f"{where}: expected sections {', '.join(SECTIONS)}")
    extra = sorted(set(entry) - set(SECTIONS))
    if extra:
        raise ValueError(
            f"{where}: unknown section {extra[0]!r}; a recipe has {', '.join(SECTIONS)}"
        )
    sections = {name: dict(entry.get(name) or {}) for name in SECTIONS}
    named = sections["algorithm"].pop("name", algorithm)
    if named not in MARL_TRAINABLE:
        raise ValueError(
            f"{where}: unknown algorithm {named!r}; bbbench trains {', '.join(MARL_TRAINABLE)} "
            f"with BenchMARL (their fallen bots masked)"
        )
    if named != algorithm:
        raise ValueError(f"{where}: the recipe is {named}'s, asked for --algo {algorithm}")
    config_class = trainable(algorithm).config_class()
    _check_fields(f"{where}, algorithm", sections["algorithm"], config_class)
    if sections["algorithm"].get("entropy_coef", 0.0) != 0.0:
        raise ValueError(
            f"{where}: entropy_coef must be 0: the entropy bonus would train the policy on "
            f"the rows of fallen bots, which the masked algorithms leave out"
        )
    _check_task(where, key, sections["task"])
    if "workers" in sections["task"]:
        check_workers(sections["task"]["workers"], None, f"{where}, task: workers")
    for name in ("model", "critic_model"):
        _check_model(f"{where}, {name}", sections[name])
    _check_recurrence(where, algorithm, sections)
    if trainable(algorithm).centralised_critic and sections["critic_model"]["name"] != "mlp":
        raise ValueError(
            f"{where}, critic_model: MAPPO's critic is centralised (it reads every bot's "
            f"observation): use name: mlp"
        )
    for field in sections["experiment"]:
        if field in OWNED:
            raise ValueError(f"{where}, experiment: {field} is bbbench train's: {OWNED[field]}")
    _check_fields(f"{where}, experiment", sections["experiment"], ExperimentConfig)
    _check_action_mode(where, algorithm, key, sections["experiment"])
    plan = MarlRecipe(
        algorithm=algorithm,
        key=key,
        task=sections["task"],
        algorithm_overrides=sections["algorithm"],
        model=sections["model"],
        critic_model=sections["critic_model"],
        experiment=sections["experiment"],
        segments=sections["segments"],
    )
    plan.check_worlds(plan.n_envs)
    check_segments(sections["segments"], plan.batch(), where)
    return plan


def check_workers(workers: Any, worlds: int | None, what: str = "--workers") -> int:
    """`workers` if it is a whole number of processes from 1 to `worlds` (if given)."""
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"{what} {workers!r}: expected a whole number of processes, at least 1")
    if worlds is not None and workers > worlds:
        raise ValueError(
            f"{what} {workers}: more worker processes than the {worlds} worlds they step; "
            f"give at most {worlds}"
        )
    return workers


def _check_fields(where: str, given: dict[str, Any], config_class) -> None:
    known = [field.name for field in dataclasses.fields(config_class)]
    for field in given:
        if field not in known:
            raise ValueError(f"{where}: {unknown('key', field, tuple(known))}")


def _check_action_mode(where: str, algorithm: str, key: str, experiment: dict) -> None:
    """`ValueError` unless the recipe's `prefer_continuous_actions` is a mode the task's
    robots take and the algorithm exports: continuous on a mixed team (its robots share no
    other mode), discrete for a recurrent actor (the board's recurrent contract)."""
    if "prefer_continuous_actions" not in experiment:
        return
    prefer = experiment["prefer_continuous_actions"]
    if prefer is not True and prefer is not False:
        raise ValueError(
            f"{where}, experiment: prefer_continuous_actions must be true or false, got {prefer!r}"
        )
    task = bbbench.spec(key)
    if task.mixed and not prefer:
        raise ValueError(
            f"{where}, experiment: prefer_continuous_actions false, but {key} is a mixed team, "
            f"whose robots share continuous actions only: drop the key"
        )
    mode = "continuous" if prefer else "discrete"
    if mode not in task.action_modes:
        raise ValueError(
            f"{where}, experiment: {key} takes {' or '.join(task.action_modes)} actions, not "
            f"{mode}: set prefer_continuous_actions to {str(not prefer).lower()}"
        )
    if prefer and trainable(algorithm).recurrent:
        raise ValueError(
            f"{where}, experiment: {algorithm} exports discrete actions only (the board's "
            f"recurrent contract): drop prefer_continuous_actions"
        )


def _like(task_id: str, table: dict[str, Any]) -> str | None:
    """The task whose recipe a multi-bot task without its own trains with: one of the same
    scenario, else one whose bots end as its do (a team's together, or each alone)."""
    try:
        task = bbbench.spec(task_id)
    except ValueError:
        return None
    if not task.multi_agent or latest_version(task_id) != task_id:
        return None  # an older version keeps no recipe: the recipes train the latest
    if task.mixed:
        return None  # a mixed team acts in other spaces than any one robot's team
    known = [k for k in table if k in bbbench.list_tasks(multi_agent=True)]
    for same in (
        lambda other: other.scenario_class is task.scenario_class,
        lambda other: other.scenario_class.team == task.scenario_class.team,
    ):
        found = [k for k in known if same(bbbench.spec(k))]
        if found:
            return found[0]
    return None


def _check_task(where: str, task_id: str, keywords: dict[str, Any]) -> None:
    if not bbbench.spec(task_id).multi_agent:
        raise ValueError(f"{where}: not a multi-bot task")
    defaults = task_config(task_id)
    for field in keywords:
        if field not in defaults:
            raise ValueError(
                f"{where}, task: unknown keyword {field!r}; the task takes {', '.join(defaults)}"
            )
    try:  # the env's own checks of its keywords' values (it builds no world until reset)
        env_kwargs = {key: value for key, value in keywords.items() if key != "workers"}
        bbbench.make_parallel(task_id, **env_kwargs).close()
    except (TypeError, ValueError) as error:
        raise ValueError(f"{where}, task: {error}") from None


def _check_recurrence(where: str, algorithm: str, sections: dict[str, Any]) -> None:
    """A recurrent method's actor is BenchMARL's GRU, and only a recurrent method's; the
    critic stays an MLP or the encoder (what the board plays is the actor)."""
    recurrent = trainable(algorithm).recurrent
    if (sections["model"]["name"] == "gru") != recurrent:
        raise ValueError(
            f"{where}, model: {algorithm}'s actor is "
            + (
                "name: gru (its method is recurrent)"
                if recurrent
                else "not a GRU: train it as "
                f"{algorithm}-gru, whose board entry says it is recurrent"
            )
        )
    if sections["critic_model"]["name"] == "gru":
        raise ValueError(
            f"{where}, critic_model: a GRU critic is not trained here; the critic is an "
            f"mlp or the neighbour encoder (the recurrence is the actor's)"
        )


def _torch_class(name: Any) -> type:
    return getattr(torch.nn, str(name).removeprefix("torch.nn."))


def _check_model(where: str, section: dict[str, Any]) -> None:
    name = section.get("name")
    if name is None:
        raise ValueError(f"{where}: give its name: {' or '.join(MODELS)}")
    if name not in MODELS:
        raise ValueError(
            f"{where}: unknown model {name!r}; bbbench's recipes take {' or '.join(MODELS)} "
            f"(a model the board can score: it exports to ONNX)"
        )
    fields = {k: v for k, v in section.items() if k != "name"}
    if name == "neighbour_encoder":
        allowed = ("embed", "hidden", "pool")
        for field in fields:
            if field not in allowed:
                raise ValueError(
                    f"{where}: the neighbour encoder takes {', '.join(allowed)}, not {field!r}"
                )
        if fields.get("pool", "mean") not in ("mean", "max"):
            raise ValueError(f"{where}: pool {fields['pool']!r}: mean or max")
        return
    if name == "gru":
        for field in fields:
            if field not in _GRU_FIELDS:
                raise ValueError(
                    f"{where}: the GRU takes {', '.join(_GRU_FIELDS)} (one layer, as the "
                    f"board's recurrent contract carries), not {field!r}"
                )
        _check_activation(where, fields.get("mlp_activation_class"), "mlp_activation_class")
        return
    _check_fields(where, fields, MlpConfig)
    for key in ("layer_class", "norm_class"):
        if fields.get(key) not in (None, "torch.nn.Linear" if key == "layer_class" else None):
            raise ValueError(
                f"{where}: {key} {fields[key]!r}: the board's ONNX reader runs Linear layers only"
            )
    _check_activation(where, fields.get("activation_class"), "activation_class")


def _check_activation(where: str, activation: Any, key: str) -> None:
    if activation is not None and str(activation).removeprefix("torch.nn.") not in _ACTIVATIONS:
        raise ValueError(
            f"{where}: {key} {activation!r}: one of "
            f"{', '.join('torch.nn.' + a for a in _ACTIVATIONS)}"
        )

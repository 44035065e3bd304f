"""The BenchMARL route: `bbbench train TASK --algo mappo` (or ippo), BenchMARL's
`Experiment` with a recipe of `bbbench/training/recipes/`, on one multi-bot or team task.

The policy shared by every bot is exported to ONNX (`bbbench.policies.export_onnx`, with
its contract) at every evaluation point, and that file plays the task's training seeds
(`bbbench.training.evaluation_seeds`, never an eval seed) as `bbbench eval` would play
it: the curve is the board's own arithmetic. The policy written to `--out` is the last
one (`CHECKPOINT_RULE`): the best of ten evaluations on a dozen training episodes each
is a lucky pick, flattered by about 1.5 standard errors of its mean, and evaluating
every candidate on enough episodes to make the pick fair would cost more than the
training. Written beside it, as for stable-baselines3: `curve.json`, `curve.png`,
`train.json`, `results.json`.

A budget is trained in whole batches (at least one), and evaluated at most once a
batch. The worlds are collected in one batched env (`bbbench.marl.batched_env`),
stepped in `workers` processes; seeded (BenchMARL's `seed_everything`, world k's first
episode on seed + k), collected on one torch thread and updated on a fixed two
(`recipes.UPDATE_THREADS`), so the same call writes the same bytes for any number of
workers, on any machine of one kind.
"""

from __future__ import annotations

import contextlib
import gc
import logging
import os
import platform
import tempfile
import time
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import benchmarl
import numpy as np
import torch
import torchrl
from benchmarl.experiment import Experiment
from benchmarl.experiment import experiment as benchmarl_experiment
from benchmarl.experiment.callback import Callback
from benchmarl.models import Gru

import bbbench
from bbbench.envs.worlds import GROUP, agent_groups, group_slots
from bbbench.evaluation import evaluate
from bbbench.evaluation.episodes import LockstepPlayer
from bbbench.files import write_atomic
from bbbench.marl.models import DeterministicAction, NeighbourEncoderModel, RecurrentActor
from bbbench.policies import classical_controller, load_policy, onnx_bytes
from bbbench.policies.onnx.policy import OnnxPolicy
from bbbench.policies.onnx.reader import parse_onnx
from bbbench.policies.onnx.team import TeamFilePolicy, team_bytes
from bbbench.policies.policy import RandomActor, TeamActor
from bbbench.tasks.channel import MESSAGE_FIELD
from bbbench.tasks.suite import agent_layout
from bbbench.training.benchmarl.recipes import MarlRecipe, marl_recipe
from bbbench.training.benchmarl.segments import Segments, segment_seed
from bbbench.training.beside import trainings_beside
from bbbench.training.checks import schedule
from bbbench.training.logs import Trained, curve_point, write_logs
from bbbench.training.seeds import evaluation_seeds

CHECKPOINT_RULE = "last"  # the policy written: the last one, never a lucky best


# World steps of the classical controller's play the observation statistics are measured
# on, and the share of its actions replaced by random ones (to visit recoveries too).
STATISTICS_STEPS = 2000
STATISTICS_EPSILON = 0.2


def observation_statistics(
    task_id: str, config: dict[str, Any], seed: int, action_mode: str
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Mean and standard deviation of each observation value over `STATISTICS_STEPS`
    world steps of the task's classical controller in `action_mode` (the recipe's,
    `MarlRecipe.action_mode`; `STATISTICS_EPSILON` of its actions random; seeded), pooled
    over the bots still playing of each agent group (`bot`; on a mixed team, each
    robot's: `bbbench.envs.worlds.agent_groups`): the fixed normalizer the models see
    observations through (a value that varies by less than 0.01 there is
    left unscaled; a slot's presence bit, `Slots.presence_columns`, is left as it is,
    0 or 1, since the neighbour encoder multiplies its slot by it: standardized, the
    nearest sender's bit on Rendezvous-v0, present in every row, read 0, and hid that
    sender). These are the states a standing bot visits. Under random play the
    bots are falling, and the pitch's spread there (0.36 rad on MultiBalance-v1, against
    0.05 rad) hides the hundredths of a radian balancing is made of: with statistics of
    random play, or raw observations, IPPO and MAPPO fell more as they trained
    (docs/notebook.md, "BenchMARL: IPPO and MAPPO")."""
    env = bbbench.make_parallel(task_id, action_mode=action_mode, **config)
    controller = load_policy(classical_controller(task_id), action_mode=action_mode).actor(task_id)
    team = isinstance(controller, TeamActor)
    group_of = {bot: group for group, bots in agent_groups(env.task).items() for bot in bots}
    seen: dict[str, list[np.ndarray]] = {group: [] for group in dict.fromkeys(group_of.values())}
    rng = np.random.default_rng([seed, 7])
    observations, _ = env.reset(seed=seed)
    for _ in range(STATISTICS_STEPS):
        bots = list(env.agents)
        indices = [env.possible_agents.index(bot) for bot in bots]
        rows = [observations[bot] for bot in bots]
        for index, row in zip(indices, rows, strict=True):
            seen[group_of[index]].append(row)
        chosen = controller.team(rows, indices) if team else controller(np.stack(rows), None)
        actions = {
            bot: RandomActor(env.action_space(bot))(None, [rng])[0]
            if rng.random() < STATISTICS_EPSILON
            else chosen[i]
            for i, bot in enumerate(bots)
        }
        observations, _, _, _, _ = env.step(actions)
        if not env.agents:
            observations, _ = env.reset(seed=int(rng.integers(2**31)))
    layouts = group_slots(env.task)
    env.close()
    statistics = {}
    for group, rows in seen.items():
        values = np.asarray(rows, np.float64)
        mean, std = values.mean(axis=0), values.std(axis=0)
        std = np.where(std < 0.01, 1.0, std)
        slots = layouts[group]
        flags = list(slots.presence_columns()) if slots is not None else []
        mean[flags], std[flags] = 0.0, 1.0
        statistics[group] = (mean.astype(np.float32), std.astype(np.float32))
    return statistics


def heard_mask(task_id: str, config: dict[str, Any]) -> np.ndarray | None:
    """For a training with the messages muted (`mute_messages`), the observation mask its
    exported policy is given: 0 at every message value, 1 elsewhere, so that it hears
    nothing in any env, as it trained (the board scores it on the task as it is); None
    for any other training."""
    if not config.get("mute_messages"):
        return None
    names = agent_layout(task_id)
    return np.array([0.0 if MESSAGE_FIELD.fullmatch(name) else 1.0 for name in names], np.float32)


def team_file(
    experiment: Experiment,
    task_id: str,
    algorithm: str,
    normalization: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
    **contract: Any,
) -> bytes:
    """A mixed team's trained policies as one team file (`bbbench.policies.onnx.team`):
    each robot group's actor, deterministic, written to ONNX with that group's spaces
    and its `normalization` (mean, std), if the models saw observations through one;
    `contract`: `onnx_bytes`'s other fields (training_steps, training_seed)."""
    models = {}
    for group in experiment.group_map:
        actor = exported_actor(experiment, group, "continuous")
        mean, std = (normalization or {}).get(group, (None, None))
        models[group] = onnx_bytes(
            actor, task_id, algorithm=algorithm, group=group, mean=mean, std=std, **contract
        )
    return team_bytes(models)


def actor_network(experiment: Experiment, group: str = "bot") -> torch.nn.Module:
    """The torch network of a group's policy (every bot's, but on a mixed team): observation
    -> action scores, or a continuous policy's loc and scale (a recurrent one's,
    `RecurrentActor`: (observation, state) -> (scores, next state))."""
    policy = experiment.group_policies[group]
    for module in policy.modules():
        if isinstance(module, NeighbourEncoderModel):
            return module.net
        if isinstance(module, Gru):
            return RecurrentActor(module)
        if hasattr(module, "mlp") and hasattr(module.mlp, "get_stateful_net"):
            return module.mlp.get_stateful_net()
    raise TypeError(f"no exportable network in {type(policy).__name__}")


def exported_actor(experiment: Experiment, group: str, action_mode: str) -> torch.nn.Module:
    """The network a group's policy file holds: `actor_network`; in continuous actions,
    deterministic (`DeterministicAction`: the tanh of its loc, the action's width read
    from the experiment's spec)."""
    network = actor_network(experiment, group)
    if action_mode == "continuous":
        actions = experiment.action_spec[group, "action"].shape[-1]
        network = DeterministicAction(network, actions)
    return network


class TrainingEvaluation(Callback):
    """After each training iteration: progress; every `every` frames, the policy exported
    and played on the training seeds, a point of the curve; the last file kept."""

    def __init__(
        self,
        task_id,
        every,
        began,
        on_progress,
        budget,
        bots,
        algorithm,
        normalization,
        seed,
        mask,
        action_mode,
    ):
        super().__init__()
        self.task_id, self.every = task_id, every
        self.normalization = normalization  # (mean, std) by agent group
        self.mixed = bbbench.spec(task_id).mixed
        self.mask = mask  # `heard_mask`: what the exported policy hears
        self.action_mode = action_mode  # the recipe's: `MarlRecipe.action_mode`
        self.began, self.on_progress, self.budget = began, on_progress, budget
        self.bots, self.algorithm, self.seed = bots, algorithm, seed
        self.next_at = every
        self.curve: list[dict[str, float]] = []
        self.last: bytes | None = None
        self.player = LockstepPlayer(actors={}, action_mode=self.action_mode, sampled=False)

    def __getstate__(self) -> dict[str, Any]:
        """BenchMARL pickles its callbacks beside a run (to restore it): without the
        progress hook (a closure, often)."""
        return {**self.__dict__, "on_progress": None}

    def on_train_end(self, training_td, group: str) -> None:
        frames = self.experiment.total_frames
        if frames >= self.next_at:
            self.next_at += self.every
            self.evaluate_now()
        elif self.on_progress is not None:
            self.on_progress(frames, self.budget, None)

    def evaluate_now(self) -> None:
        frames = self.experiment.total_frames
        if self.curve and self.curve[-1]["steps"] == frames:
            return
        contract = {
            "algorithm": self.algorithm.upper(),
            "training_steps": frames,  # world steps: the board's unit
            "training_seed": self.seed,
        }
        if self.mixed:
            candidate = team_file(
                self.experiment, self.task_id, **contract, normalization=self.normalization
            )
            policy = TeamFilePolicy.from_bytes(candidate, "candidate.zip")
        else:
            network = exported_actor(self.experiment, GROUP, self.action_mode)
            mean, std = self.normalization[GROUP]
            candidate = onnx_bytes(
                network,
                self.task_id,
                state_width=getattr(network, "state_width", None),
                action_mode=self.action_mode,
                mean=mean,
                std=std,
                mask=self.mask,
                **contract,
            )
            policy = OnnxPolicy(parse_onnx(candidate, "the candidate policy", "candidate.onnx"))
        self.player.actors[self.task_id] = policy.actor(self.task_id)
        played = self.player.play(self.task_id, evaluation_seeds(self.task_id))
        point = curve_point(played, self.began, steps=frames, bot_steps=frames * self.bots)
        self.curve.append(point)
        self.last = candidate
        if self.on_progress is not None:
            self.on_progress(frames, self.budget, point)

    def state(self) -> dict[str, Any]:
        """What a resumed training needs of this callback (`bbbench.training.benchmarl.
        segments`): the curve, the next evaluation, the last policy and the time so far."""
        return {
            "curve": self.curve,
            "next_at": self.next_at,
            "last": self.last,
            "elapsed_s": time.perf_counter() - self.began,
        }

    def load_state(self, state: dict[str, Any]) -> None:
        """This callback as `state()` left it, its clock going on from there."""
        self.curve, self.next_at, self.last = list(state["curve"]), state["next_at"], state["last"]
        self.began = time.perf_counter() - state["elapsed_s"]

    def close(self) -> None:
        self.player.close()


def train_marl(
    task_id: str,
    algorithm: str,
    out: str | Path,
    steps: int | None = None,
    seed: int = 0,
    n_envs: int | None = None,
    log_dir: str | Path | None = None,
    eval_freq: int | None = None,
    final_episodes: int | None = None,
    on_progress: Callable[[int, int, dict | None], None] | None = None,
    recipe_file: str | Path | None = None,
    workers: int | None = None,
):
    """Train `algorithm` (ippo, mappo) on the multi-bot task `task_id` with BenchMARL and
    its recipe; write the last policy, as ONNX, to `out` and the logs beside it.

    `steps` (world steps, BenchMARL's frames; at least one batch), `n_envs` (worlds
    collected at once, in one batched env) and `workers` (the processes that step them)
    default to the recipe's; `eval_freq` to a tenth of the budget and at least a batch,
    at the end of the training iteration that reaches it."""
    plan: MarlRecipe = marl_recipe(algorithm, task_id, recipe_file)
    run = schedule(plan, algorithm, [task_id], out, n_envs, workers, steps, log_dir, eval_freq)
    budget, n_envs, out, log_dir, eval_freq = (
        run.budget,
        run.n_envs,
        run.out,
        run.log_dir,
        run.eval_freq,
    )
    task = plan.task_config()
    if workers is not None:
        task.config["workers"] = workers
    bots = task.config["n_bots"]  # the recipe's, which may differ from the task's default

    torch.set_num_threads(1)  # the same bytes on every run, and no oversubscription
    began = time.perf_counter()
    fingerprint = {
        "task": task_id,
        "algorithm": algorithm,
        "seed": seed,
        "steps": budget,
        "n_envs": n_envs,
        "eval_freq": eval_freq,
        "recipe": plan.record(),
        "versions": {name: str(version) for name, version in _versions().items()},
    }
    segments = Segments(plan.segment_frames, budget, log_dir, fingerprint)
    saved = segments.restore()  # before any work: a folder of another training is refused
    task.observation_normalization = observation_statistics(
        task_id, task.env_kwargs, seed, plan.action_mode
    )
    with (
        _quiet(),
        trainings_beside() as beside,
        tempfile.TemporaryDirectory(dir=log_dir, prefix=".training-") as scratch,
    ):
        callback = TrainingEvaluation(
            task_id,
            eval_freq,
            began,
            on_progress,
            budget,
            bots,
            algorithm,
            task.observation_normalization,
            seed,
            heard_mask(task_id, task.env_kwargs),
            plan.action_mode,
        )
        if saved is not None:
            callback.load_state(saved["callback"])
            began = callback.began
        experiment = None
        try:
            for index, length in segments.remaining(saved):
                experiment = plan.build_experiment(
                    task, segment_seed(seed, index), length, n_envs, Path(scratch), [callback]
                )
                if saved is not None:
                    segments.load(experiment, saved)
                _run(experiment)
                frames = experiment.total_frames  # to this segment's end
                if frames < budget:  # a segment's end: saved, and read back as a resume reads it
                    segments.save(experiment, frames, callback.state())
                    saved = segments.read_back()
                else:
                    callback.evaluate_now()  # the end of the budget is a point of the curve
                experiment.close()
        finally:  # at the end, or interrupted (Ctrl-C, SIGTERM)
            callback.close()
            # TorchRL's replay buffers hold multiprocessing locks, unlinked when they are
            # collected: collected now, as `bbbench`'s quick exit (os._exit) skips teardown
            # and the resource tracker would warn of leaked semaphores.
            callback.experiment = experiment = None
            gc.collect()
    seconds = time.perf_counter() - began
    write_atomic(out, callback.last)
    segments.finish()

    results = evaluate(load_policy(out), [task_id], episodes=final_episodes).document
    record = {
        "tasks": [task_id],
        "action_mode": plan.action_mode,
        "seed": seed,
        "steps": frames,
        "bot_steps": frames * bots,
        "n_envs": n_envs,
        "workers": min(int(task.config.get("workers", 1)), n_envs),
        "eval_freq": eval_freq,
        "evaluation_seeds": {task_id: evaluation_seeds(task_id)},
        "checkpoint_rule": CHECKPOINT_RULE,
        "observation_statistics": {
            "controller": classical_controller(task_id),
            "world_steps": STATISTICS_STEPS,
            "random_share": STATISTICS_EPSILON,
            "presence_bits": "unscaled",  # trainings before this key standardized them
        },
        "kept": callback.curve[-1],
        "wall_time_s": round(seconds, 1),
        **({"resumed_at": segments.resumed_at} if segments.resumed_at else {}),
        "trainings_beside": beside.record(),
        "machine": f"{platform.machine()}, {os.cpu_count()} CPU(s), {platform.processor()}",
        "recipe": plan.record(),
        "versions": _versions(),
    }
    write_logs(log_dir, callback.curve, [task_id], algorithm, record, results)
    return Trained(
        out, log_dir, None, callback.curve, results, seconds, plan, kept=callback.curve[-1]
    )


def _run(experiment) -> None:
    """BenchMARL's `Experiment.run`, which closes the experiment itself when it raises.
    Closing after a Ctrl-C can fail inside TorchRL (a module left mid-call): that is the
    interruption, and is raised as one."""
    try:
        experiment.run()
    except Exception as error:
        if isinstance(error.__context__, KeyboardInterrupt):
            raise KeyboardInterrupt from None
        raise


class _NoBar:
    """What BenchMARL's loop asks of its tqdm bar, doing nothing: tqdm, even disabled,
    makes a multiprocessing lock that lives to the end of the process (and `bbbench`'s
    quick exit would leave it to the resource tracker, which warns of it)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        pass

    def update(self, *args: Any, **kwargs: Any) -> None:
        pass

    def set_description(self, *args: Any, **kwargs: Any) -> None:
        pass

    def close(self) -> None:
        pass


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """BenchMARL's own progress bar off (bbbench train draws one), TorchRL's notes and
    its warnings about versions it was not tested with left out."""
    bar, logger = benchmarl_experiment.tqdm, logging.getLogger("torchrl")
    level = logger.level
    benchmarl_experiment.tqdm = _NoBar
    logger.setLevel(logging.WARNING)
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", "PettingZoo in TorchRL is tested", UserWarning)
            warnings.filterwarnings("ignore", "SyncDataCollector has been deprecated")
            warnings.filterwarnings("ignore", "No episode terminated this iteration")
            # BenchMARL wraps a recurrent model's env in its own transforms (InitTracker,
            # the state primer): TorchRL's note on a future default of nested envs.
            warnings.filterwarnings("ignore", "The default behavior of TransformedEnv")
            yield
    finally:
        benchmarl_experiment.tqdm = bar
        logger.setLevel(level)


def _versions() -> dict[str, Any]:
    return {
        "benchmarl": benchmarl.__version__,
        "torchrl": torchrl.__version__,
        "torch": torch.__version__,
    }

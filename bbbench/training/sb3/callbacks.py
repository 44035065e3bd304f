"""The evaluation `bbbench train` runs while it trains: a point of the learning curve every
`eval_freq` steps, and the best policy so far kept."""

from __future__ import annotations

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecNormalize

from bbbench.evaluation.episodes import LockstepPlayer
from bbbench.evaluation.play import PlayedEpisode
from bbbench.policies.policy import NormalizedActor, TorchActor
from bbbench.policies.sb3.vecnormalize import live_statistics
from bbbench.training.logs import curve_point
from bbbench.training.seeds import evaluation_seeds


class TrainingEvaluation(BaseCallback):
    """Every `every` steps: play the tasks' training evaluation seeds deterministically,
    add a point to the curve, and save the model when its mean return is the best."""

    def __init__(self, tasks, mode, every, best_path, began, on_progress, budget) -> None:
        super().__init__()
        self.tasks, self.every, self.best_path = tasks, every, best_path
        self.began, self.on_progress, self.budget = began, on_progress, budget
        self.mode = mode
        self.next_at = every
        self.curve: list[dict[str, float]] = []
        self.best = -np.inf
        self.best_statistics = best_path.with_suffix(".pkl")  # under VecNormalize
        self.runner: LockstepPlayer | None = None

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.next_at:
            self.next_at += self.every
            self.evaluate_now(self.model)
        elif self.on_progress is not None and self.n_calls % 64 == 0:
            self.on_progress(self.num_timesteps, self.budget, None)
        return True

    def evaluate_now(self, model) -> None:
        if self.curve and self.curve[-1]["steps"] == model.num_timesteps:
            return
        actor = TorchActor(model.policy)
        normalized = isinstance(model.get_env(), VecNormalize)
        if normalized:  # the observations as the training env shows them now
            actor = NormalizedActor(actor, live_statistics(model.get_env()))
        self.runner = self.runner or LockstepPlayer(actors={}, action_mode=self.mode, sampled=False)
        for task_id in self.tasks:
            self.runner.actors[task_id] = actor
        played: list[PlayedEpisode] = []
        for task_id in self.tasks:
            played += self.runner.play(task_id, evaluation_seeds(task_id))
        point = curve_point(played, self.began, steps=model.num_timesteps)
        self.curve.append(point)
        if point["mean"] > self.best:
            self.best = point["mean"]
            model.save(self.best_path)
            if normalized:
                model.get_env().save(self.best_statistics)
        if self.on_progress is not None:
            self.on_progress(self.num_timesteps, self.budget, point)

    def close(self) -> None:
        if self.runner is not None:
            self.runner.close()

"""The algorithms `bbbench train` trains: one table, read by both routes.

An algorithm trains through one of two routes, each a package beside this module:

- `sb3`: stable-baselines3 (and sb3-contrib) on single-bot tasks, and on a multi-bot
  task with one policy shared by its bots, from an rl-zoo3 recipe file; it writes a zip.
- `benchmarl`: BenchMARL (TorchRL) on multi-bot and team tasks, from a recipe of
  BenchMARL's config groups; it writes the shared policy as ONNX.

A stable-baselines3 algorithm is trainable when the zip format knows it
(`bbbench.policies.sb3.algorithms`, what the reader and rebuild need) and a recipe file is
shipped for it (`bbbench/training/recipes/<key>.yml`). A BenchMARL algorithm names its
config class here (its masked version, `bbbench.marl.algorithms`). Adding an algorithm
is a row here (or a record in the zip format's table) and its recipe file.
"""

from __future__ import annotations

import dataclasses
import importlib

from bbbench.policies.sb3.algorithms import SB3_ALGORITHMS, unknown
from bbbench.training.recipe_files import recipe_file

SB3 = "sb3"
BENCHMARL = "benchmarl"


@dataclasses.dataclass(frozen=True)
class Trainable:
    """An algorithm `bbbench train --algo <key>` trains."""

    key: str  # on the command line and in its recipe file's name: "ppo", "mappo"
    route: str  # SB3 or BENCHMARL
    action_modes: tuple[str, ...]  # the modes it learns in; the first is its default
    config: str | None = None  # BenchMARL: its config class, "module:Name"
    # BenchMARL: an actor with a GRU (BenchMARL's `Gru` model, exported with its state),
    # the method's name saying so ("ippo-gru"); its recipe file's model is `name: gru`.
    recurrent: bool = False

    @property
    def name(self) -> str:
        return self.key.upper()

    @property
    def suffix(self) -> str:
        """The policy file it writes: a stable-baselines3 zip, or ONNX."""
        return ".zip" if self.route == SB3 else ".onnx"

    @property
    def centralised_critic(self) -> bool:
        """MAPPO's critic reads every bot's observation."""
        return self.config is not None and self.config.endswith("MappoConfig")

    @property
    def multi_agent_only(self) -> bool:
        """Trains the bots of a multi-bot task, and nothing else."""
        return self.route == BENCHMARL

    def config_class(self) -> type:
        """Its BenchMARL config class (imported now: needs the marl extra)."""
        module, name = self.config.split(":")
        return getattr(importlib.import_module(module), name)


ALGORITHMS: dict[str, Trainable] = {
    **{
        a.key: Trainable(a.key, SB3, a.action_modes)
        for a in SB3_ALGORITHMS.values()
        if recipe_file(a.key).is_file()
    },
    **{
        key: Trainable(key, BENCHMARL, ("discrete",), config, recurrent=gru)
        for base, config in (
            ("ippo", "bbbench.marl.algorithms:MaskedIppoConfig"),
            ("mappo", "bbbench.marl.algorithms:MaskedMappoConfig"),
        )
        for key, gru in ((base, False), (f"{base}-gru", True))
    },
}
# The keys of each route, in the table's order.
TRAINABLE = tuple(key for key, a in ALGORITHMS.items() if a.route == SB3)
MARL_TRAINABLE = tuple(key for key, a in ALGORITHMS.items() if a.route == BENCHMARL)


def trainable(key: str) -> Trainable:
    """The algorithm `--algo key` trains; `ValueError` naming the ones there are."""
    if key not in ALGORITHMS:
        raise ValueError(unknown("algorithm", key, tuple(ALGORITHMS)))
    return ALGORITHMS[key]

"""A BenchMARL training in segments, which resumes where it was stopped.

A recipe's `segments: {frames: N}` cuts a training into segments of N world steps (the
last one perhaps shorter). At each segment's end the training is saved to `resume.pt`
in its log folder: the models and the loss modules' state (BenchMARL's `losses`), the
optimizers' state, and the curve so far with the last exported policy. Segment s is a
new BenchMARL `Experiment` of the same recipe, seeded with `segment_seed(seed, s)` (its
torch, NumPy and Python generators, and every world's next episode, as BenchMARL seeds
an experiment), that loads the saved state before it collects.

A run never stopped goes through the same save and load at every segment's end, so a
run stopped mid-segment and started again (the same command) writes the same bytes as
one never stopped: it repeats the segment it was in, from its start. Without the key a
training is one segment on the training's own seed, as before it existed.

The saved file names what it is a training of (`fingerprint`); a different training
asked for in its folder is refused rather than mixed with it. The file is removed when
the training ends.
"""

from __future__ import annotations

import io
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import torch

from bbbench.files import write_atomic
from bbbench.training.checks import StoppedTrainingError

RESUME_FILE = "resume.pt"


def segment_seed(seed: int, index: int) -> int:
    """The seed of segment `index` of a training on `seed`: the seed itself for the first
    (a training of one segment is what it was), then one drawn from (seed, index), a
    training seed (below 2**30, so that world k's seed + k stays one)."""
    if index == 0:
        return seed
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0] % 2**30)


def check_segments(section: dict[str, Any], batch: int, where: str) -> int | None:
    """The world steps of a recipe's segment (`segments: {frames: N}`), None for a
    training of one segment; `ValueError` unless N is a whole number of batches."""
    unknown = sorted(set(section) - {"frames"})
    if unknown:
        raise ValueError(f"{where}, segments: unknown key {unknown[0]!r}; it takes frames")
    frames = section.get("frames")
    if frames is None:
        return None
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < batch:
        raise ValueError(
            f"{where}, segments: frames {frames!r}: expected a whole number of world steps, "
            f"at least a batch ({batch:,})"
        )
    if frames % batch:
        raise ValueError(
            f"{where}, segments: frames {frames:,} is not a whole number of batches of "
            f"{batch:,} world steps: give a multiple of {batch:,}"
        )
    return frames


class Segments:
    """The segments of one training of `budget` world steps, `frames` each (None: one),
    saved to and resumed from `folder / RESUME_FILE`; `fingerprint` names the training."""

    def __init__(self, frames: int | None, budget: int, folder: Path, fingerprint: dict) -> None:
        self.frames = frames or budget
        self.budget = budget
        self.path = Path(folder) / RESUME_FILE
        self.fingerprint = fingerprint
        self.resumed_at: list[int] = []  # the world steps this call started from, if any

    def restore(self) -> dict[str, Any] | None:
        """The saved state of this training if its folder holds one, else None;
        `StoppedTrainingError` if it holds another training's."""
        if not self.path.exists():
            return None
        try:
            saved = self.read_back()
            theirs, saved["frames"] = saved["fingerprint"], int(saved["frames"])
        except Exception as error:  # not a file `save` wrote: said, not resumed from
            raise StoppedTrainingError(
                f"{self.path}: not a stopped training bbbench can resume "
                f"({type(error).__name__}); remove it to start afresh"
            ) from None
        for key, value in self.fingerprint.items():
            if theirs.get(key) != value:
                shown = (
                    ""
                    if isinstance(value, dict)
                    else f" ({theirs.get(key)!r}, asked for {value!r})"
                )
                raise StoppedTrainingError(
                    f"{self.path}: a stopped training of another {key}{shown}; give its "
                    f"command again to resume it, or remove the file to start this one afresh"
                )
        self.resumed_at.append(saved["frames"])
        return saved

    def remaining(self, saved: dict[str, Any] | None) -> Iterator[tuple[int, int]]:
        """(index, world steps) of each segment still to train, after `saved`'s."""
        start = 0 if saved is None else saved["frames"]
        while start < self.budget:
            yield start // self.frames, min(self.frames, self.budget - start)
            start += self.frames

    def save(self, experiment, frames: int, callback_state: dict[str, Any]) -> None:
        """The training after `frames` world steps, for the next segment to load."""
        optimizers = {
            group: {name: optimizer.state_dict() for name, optimizer in named.items()}
            for group, named in experiment.optimizers.items()
        }
        state = {
            "fingerprint": self.fingerprint,
            "frames": frames,
            "losses": {group: loss.state_dict() for group, loss in experiment.losses.items()},
            "optimizers": optimizers,
            "callback": callback_state,
        }
        buffer = io.BytesIO()
        torch.save(state, buffer)
        write_atomic(self.path, buffer.getvalue())

    def load(self, experiment, saved: dict[str, Any]) -> None:
        """`experiment` (a new segment's) as the training was when `saved`."""
        for group, loss in experiment.losses.items():
            loss.load_state_dict(saved["losses"][group])
        for group, named in experiment.optimizers.items():
            for name, optimizer in named.items():
                optimizer.load_state_dict(saved["optimizers"][group][name])
        if hasattr(experiment, "collector"):  # the collector's policy as the losses' now
            experiment.collector.update_policy_weights_()
        experiment.total_frames = saved["frames"]

    def read_back(self) -> dict[str, Any]:
        """What the file holds: what the last `save` wrote, read back as a resumed run
        reads it (a run never stopped loads it from the file too, the same way)."""
        return torch.load(io.BytesIO(self.path.read_bytes()), weights_only=True)

    def finish(self) -> None:
        """The training is done: its saved state is not needed."""
        self.path.unlink(missing_ok=True)

"""How many trainings ran beside this one on this machine, as measured rather than as
asked: a training's wall time (on the board, in train.json) means little without it.

Each training holds an exclusive `flock` on a file of its own in one folder of the
machine's temporary directory for as long as it runs; a thread of its own counts the
other files held, every `every` seconds. A lock dies with its process, so a training
that was killed is never counted (its file is removed by the next one that looks).
Trainings that do not share a temporary directory (`TMPDIR`) do not see each other.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import tempfile
import threading
import uuid
from collections.abc import Iterator
from pathlib import Path

from bbbench.portable import total

FOLDER = "bbbench-trainings"
EVERY_S = 5.0


class Beside:
    """The counts sampled so far; `record()` is what train.json keeps."""

    def __init__(self, folder: Path, own: Path) -> None:
        self.folder, self.own = folder, own
        self.counts: list[int] = []

    def sample(self) -> int:
        """The trainings running now besides this one (counted, and returned)."""
        count = 0
        for path in self.folder.glob("*.lock"):
            if path == self.own:
                continue
            try:
                with open(path, "rb") as other:
                    fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:  # held: a training running
                count += 1
            except FileNotFoundError:  # it ended while we looked
                continue
            else:  # free: its training died without removing it
                path.unlink(missing_ok=True)
        self.counts.append(count)
        return count

    def record(self) -> dict[str, float | int]:
        """The most trainings seen beside this one at once, their mean over the run,
        and how many times they were counted."""
        counts = self.counts or [0]
        return {
            "most": max(counts),
            "mean": round(total(counts) / len(counts), 2),
            "samples": len(self.counts),
        }


@contextlib.contextmanager
def trainings_beside(every: float = EVERY_S, root: str | Path | None = None) -> Iterator[Beside]:
    """Hold this training's lock, and count the others every `every` seconds (and at
    the start and the end) until the block ends."""
    folder = Path(root or tempfile.gettempdir()) / FOLDER
    folder.mkdir(exist_ok=True)
    own = folder / f"{os.getpid()}-{uuid.uuid4().hex}.lock"
    stop = threading.Event()
    with open(own, "wb") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        beside = Beside(folder, own)
        beside.sample()

        def count() -> None:
            while not stop.wait(every):
                beside.sample()

        thread = threading.Thread(target=count, name="trainings-beside", daemon=True)
        thread.start()
        try:
            yield beside
        finally:
            stop.set()
            thread.join()
            beside.sample()
            own.unlink(missing_ok=True)


def described(record: dict[str, float | int] | None) -> str:
    """The board's words for a record of `Beside` ("one training", "2 trainings side by
    side", "up to 2 trainings side by side (1.4 on average)"); "" without a record."""
    if record is None:
        return ""
    most, mean = int(record["most"]), float(record["mean"])
    if most == 0:
        return "one training"
    if mean == most:
        return f"{most + 1} trainings side by side"
    return f"up to {most + 1} trainings side by side ({mean + 1:.1f} on average)"

"""Many trainings at once: one per seed, here one after another or as Ray tasks.

`bbbench train TASK --algo A --seeds 0,1,2 --out runs/policy.zip` trains seed s
into `runs/policy-s<s>/` (the zip, its statistics where rl-zoo3 puts them, and
curve.json, curve.png, train.json, results.json), each as reproducible as a
single `--seed s` run: the same bytes. Every seed trains in a fresh process (a
spawned one here, a fresh Ray worker there), as a `--seed` run does. Not for the
bytes: two trainings in one process give each its own (tests/test_train_fanout.py).
For what a training leaves in its process: torch's and BenchMARL's memory, pybullet
connections, a worker stuck after a crash. A fresh process per seed gives each seed a
clean machine, and frees all of it when the seed ends.

With `--backend ray [--address HOST:PORT]` every seed is a Ray task (one CPU
each) on a local Ray or a cluster. The task trains in a folder of its own on
whichever machine runs it and returns its files' bytes; this machine writes them
(atomically), so a cluster needs no shared filesystem.

Each seed sends the points of its curve back as it draws them (a queue: a manager's
here, a Ray actor there), so that `on_point` tells how every seed is going while they
train, not only when one ends.
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import tempfile
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from bbbench.evaluation.backends import default_workers, import_ray, join_ray
from bbbench.files import write_all_atomic
from bbbench.training.trainer import train


@dataclasses.dataclass(frozen=True)
class SeedRun:
    """One seed's training, done: where its files are, and what it measured."""

    seed: int
    out: Path
    curve: list[dict[str, float]]
    results: dict[str, Any]
    seconds: float


def parse_seeds(text: str) -> list[int]:
    """`0,1,2` as [0, 1, 2]; `ValueError` for anything but distinct whole numbers >= 0."""
    seeds = []
    for part in text.split(","):
        part = part.strip()
        if not part.isdecimal():
            raise ValueError(
                f"--seeds {text!r}: {part!r} is not a seed; give whole numbers >= 0 "
                f"separated by commas, e.g. --seeds 0,1,2"
            )
        seeds.append(int(part))
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"--seeds {text!r}: a seed is given twice")
    return seeds


def seed_out(out: str | Path, seed: int) -> Path:
    """Where seed `seed` of `--out` goes: `runs/policy.zip` -> `runs/policy-s0/policy.zip`."""
    out = Path(out)
    return out.parent / f"{out.stem}-s{seed}" / out.name


def train_seeds(
    task_ids: Sequence[str],
    algorithm: str,
    out: str | Path,
    seeds: Sequence[int],
    backend: str = "local",
    address: str | None = None,
    on_done: Callable[[SeedRun], None] | None = None,
    on_point: Callable[[int, int, int, dict], None] | None = None,
    **keywords: Any,
) -> list[SeedRun]:
    """Train one policy per seed (`bbbench.training.train`'s keywords: action_mode, steps,
    n_envs, final_episodes), locally one after another or as Ray tasks; each seed's files
    in `seed_out(out, seed)`'s folder. `on_done(run)` as each finishes;
    `on_point(seed, steps, total, point)` at each point of a seed's curve, as it trains."""
    if keywords.get("recipe_file") is not None:  # sent as text: a Ray worker may be elsewhere
        keywords["recipe_file"] = ("text", Path(keywords["recipe_file"]).read_text())
    done: list[SeedRun] = []
    if backend == "local":
        # Each seed in a fresh process, as a `--seed` run is: what one training leaves in
        # its process (memory, connections) is freed with it (the module's docstring).
        context = multiprocessing.get_context("spawn")
        with (
            context.Manager() as manager,
            ProcessPoolExecutor(1, mp_context=context, max_tasks_per_child=1) as pool,
        ):
            points = manager.Queue()
            for seed in seeds:
                job = (list(task_ids), algorithm, Path(out).name, seed, keywords, points)
                future = pool.submit(_train_in_folder, *job)
                while not _wait_local(future, points, on_point):
                    pass
                done.append(_write(out, seed, future.result()))
                if on_done is not None:
                    on_done(done[-1])
        return done
    ray = import_ray()
    from ray.util.queue import Queue  # lazy: ray

    started = join_ray(address, min(len(seeds), default_workers()))
    try:
        points = Queue()
        # A fresh worker process for every seed (max_calls=1), as for the local backend.
        remote = ray.remote(num_cpus=1, max_calls=1)(_train_in_folder)
        futures = {
            remote.remote(list(task_ids), algorithm, Path(out).name, seed, keywords, points): seed
            for seed in seeds
        }
        while futures:
            ready, _ = ray.wait(list(futures), num_returns=1, timeout=_POLL_S)
            _drain(points, on_point)
            for future in ready:
                seed = futures.pop(future)
                done.append(_write(out, seed, ray.get(future)))
                if on_done is not None:
                    on_done(done[-1])
        _drain(points, on_point)
    finally:
        if started:
            ray.shutdown()
    return sorted(done, key=lambda run: list(seeds).index(run.seed))


_POLL_S = 1.0  # s between looks at the queue of curve points while seeds train


def _wait_local(future, points, on_point) -> bool:
    """Whether `future` is done, after handing on the points that came within a poll."""
    try:
        future.result(timeout=_POLL_S)
    except TimeoutError:
        _drain(points, on_point)
        return False
    _drain(points, on_point)
    return True


def _drain(points, on_point) -> None:
    """Hand every point in the queue to `on_point` (none, if it is None)."""
    while not points.empty():
        point = points.get()
        if on_point is not None:
            on_point(*point)


def _train_in_folder(task_ids, algorithm, name, seed, keywords, points=None) -> dict[str, Any]:
    """One seed trained in a folder of its own; its files' bytes, and what it measured.
    Each point of its curve goes into `points` (a queue) as (seed, steps, total, point)."""

    def sent(steps: int, total: int, point: dict | None) -> None:
        if point is not None and points is not None:
            points.put((seed, steps, total, point))

    with (
        tempfile.TemporaryDirectory(prefix="bbbench-train-") as folder,
        tempfile.TemporaryDirectory(prefix="bbbench-recipe-") as recipes,
    ):
        root = Path(folder)
        if keywords.get("recipe_file") is not None:  # the recipe file's text, written here
            recipe = Path(recipes) / "recipe.yml"
            recipe.write_text(keywords["recipe_file"][1])
            keywords = {**keywords, "recipe_file": recipe}
        trained = train(
            task_ids,
            algorithm,
            out=root / name,
            seed=seed,
            log_dir=root,
            on_progress=sent,
            **keywords,
        )
        files = {
            str(path.relative_to(root)): path.read_bytes()
            for path in sorted(root.rglob("*"))
            if path.is_file()
        }
    return {
        "root": str(root),
        "files": files,
        "curve": trained.curve,
        "results": trained.results,
        "seconds": trained.seconds,
    }


def _write(out: str | Path, seed: int, trained: dict[str, Any]) -> SeedRun:
    target = seed_out(out, seed)
    # train.json names the statistics' path: where they are now, not the training folder.
    root, here = trained["root"].encode(), str(target.parent).encode()
    files = {
        target.parent / name: data.replace(root, here) if name == "train.json" else data
        for name, data in trained["files"].items()
    }
    for path in files:
        path.parent.mkdir(parents=True, exist_ok=True)
    write_all_atomic(files)
    return SeedRun(
        seed=seed,
        out=target,
        curve=trained["curve"],
        results=trained["results"],
        seconds=trained["seconds"],
    )

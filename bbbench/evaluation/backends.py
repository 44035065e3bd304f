"""Where episodes run: local worker processes, or Ray tasks on a local or remote Ray.

Both take the same jobs, (task ID, a group of episode seeds), and hand back
each job's `PlayedEpisode`s, or None for a job whose worker died twice: a dead
worker's job is retried once on a fresh worker, then reported missing. Which
worker plays a job never changes its results (episodes are seeded, envs are
history-free, and a group is played the same way anywhere), so both backends
give identical results.
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import os
import signal
import socket
from collections import deque
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection, wait

from bbbench.children import die_with_parent
from bbbench.evaluation.episodes import LockstepPlayer, Players
from bbbench.evaluation.play import PlayedEpisode
from bbbench.tasks.spec import TaskSpec

Job = tuple[TaskSpec, tuple[int, ...]]  # (task, episode seeds played together)
Results = list[PlayedEpisode] | None  # a job's episodes; None if its worker died twice
OnResult = Callable[[int, Results], None]
BACKENDS = ("local", "ray")
ATTEMPTS = 2  # a job whose worker dies is tried once more


def default_workers() -> int:
    """All the cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


# glibc's mallopt parameters (malloc.h)
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
_MMAP_THRESHOLD_MAX = 32 * 1024 * 1024  # glibc's largest on 64-bit systems


def keep_freed_memory() -> None:
    """Have glibc keep memory a worker frees, for its next allocations.

    A worker closes the worlds of one task and builds those of the next, some
    30 MB each. By default glibc hands such blocks back to the kernel on free,
    and the next world faults every page in again (docs/performance.md measures
    it). The cost: a worker's memory stays at its peak. No-op where the C
    library has no mallopt.
    """
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (AttributeError, OSError):
        return
    mallopt(_M_MMAP_THRESHOLD, _MMAP_THRESHOLD_MAX)
    mallopt(_M_TRIM_THRESHOLD, 2**30)


# -- local worker processes --------------------------------------------------------


def _serve(
    connection: Connection,
    runner: LockstepPlayer | Players,
    parent: int,
    inherited: Sequence[Connection] = (),
) -> None:
    """A worker: plays the episodes it is sent, keeping its envs, until told to stop.

    `inherited`: the parent's ends of the other workers' pipes, which a forked
    worker holds copies of: closed, so that each pipe has exactly its two ends.
    """
    die_with_parent(parent)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # not the command's own handler
    for other in inherited:
        other.close()
    keep_freed_memory()
    try:
        while (job := connection.recv()) is not None:
            index, task, seeds = job
            connection.send((index, runner.play(task, seeds)))
    except (EOFError, KeyboardInterrupt):
        pass
    finally:
        runner.close()


class _Worker:
    def __init__(
        self, context, runner: LockstepPlayer | Players, siblings: Sequence[_Worker] = ()
    ) -> None:
        self.connection, child = context.Pipe()
        inherited = [w.connection for w in siblings] if context.get_start_method() == "fork" else []
        self.process = context.Process(
            target=_serve, args=(child, runner, os.getpid(), inherited), daemon=True
        )
        self.process.start()
        child.close()
        self.job: tuple[int, str, tuple[int, ...]] | None = None

    def send(self, job: tuple[int, TaskSpec, tuple[int, ...]]) -> None:
        self.job = job
        self.connection.send(job)

    def stop(self, wait: bool = True) -> None:
        """Ask the worker to finish and wait for it (up to 5 s), or kill it at once."""
        if wait:
            with contextlib.suppress(OSError):
                self.connection.send(None)
            self.process.join(timeout=5)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        self.connection.close()


def run_local(
    runner: LockstepPlayer | Players, jobs: Sequence[Job], workers: int, on_result: OnResult
) -> list[Results]:
    """Run `jobs` on `workers` processes; each process keeps its envs between episodes.

    Each worker starts on its own stretch of consecutive jobs, and when that is
    done takes jobs from the end of the longest stretch left: a worker plays few
    tasks, so it builds few worlds.
    """
    # fork starts a worker in milliseconds with the policy already in memory; the
    # workers never touch torch, which the parent may have used to load the policy.
    method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
    context = multiprocessing.get_context(method)
    results: list[Results] = [None] * len(jobs)
    size = min(workers, len(jobs))
    stretches = [
        deque(
            (index, *jobs[index])
            for index in range(k * len(jobs) // size, (k + 1) * len(jobs) // size)
        )
        for k in range(size)
    ]
    tries = [0] * len(jobs)
    pool: list[_Worker] = []
    for _ in range(size):
        pool.append(_Worker(context, runner, pool))
    finished = False
    try:
        while any(stretches) or any(worker.job for worker in pool):
            for slot, worker in enumerate(pool):
                if worker.job is None and any(stretches):
                    job = _next_job(stretches, slot)
                    tries[job[0]] += 1
                    worker.send(job)
            busy = [worker for worker in pool if worker.job is not None]
            ready = set(wait([w.connection for w in busy] + [w.process.sentinel for w in busy]))
            for slot, worker in enumerate(pool):
                if worker.job is None:
                    continue
                if worker.connection in ready:
                    try:
                        index, result = worker.connection.recv()
                    except (EOFError, OSError):
                        pass  # it died mid-answer: handled below as a death
                    else:
                        results[index] = result
                        worker.job = None
                        on_result(index, result)
                        continue
                if worker.process.sentinel in ready or not worker.process.is_alive():
                    index = worker.job[0]
                    worker.job = None
                    worker.stop()
                    pool[slot] = _Worker(context, runner, pool[:slot] + pool[slot + 1 :])
                    if tries[index] < ATTEMPTS:
                        stretches[slot].appendleft((index, *jobs[index]))
                    else:
                        on_result(index, None)
        finished = True
    finally:  # interrupted (Ctrl-C, SIGTERM, an error): no worker is left behind
        for worker in pool:
            worker.stop(wait=finished)
    return results


def _next_job(stretches: list[deque], slot: int) -> tuple[int, TaskSpec, tuple[int, ...]]:
    """The next job of worker `slot`: the first of its stretch, else the last of the
    longest stretch left."""
    if stretches[slot]:
        return stretches[slot].popleft()
    return max(stretches, key=len).pop()


# -- Ray -----------------------------------------------------------------------------

RAY_CONNECT_TIMEOUT = 10.0  # s


def import_ray():
    """The `ray` module; `ValueError` saying what to install if it is not."""
    try:
        import ray  # lazy: ray, optional (the ray extra)
    except ImportError:
        raise ValueError(
            '--backend ray: Ray is not installed here: pip install "bbbench[ray]", or leave '
            "--backend out to run on this machine"
        ) from None
    return ray


def check_ray(address: str | None) -> None:
    """`ValueError` saying what to install unless Ray is, and naming `address` unless it
    is a Ray address that answers: None or "auto" (a local Ray), or HOST:PORT /
    ray://HOST:PORT with something listening there. Ray itself retries an unreachable
    address for minutes."""
    import_ray()
    if address is None or address in ("auto", "local"):
        return
    expected = "expected HOST:PORT or ray://HOST:PORT (e.g. 10.0.0.5:6379), or auto"
    host, _, port = address.removeprefix("ray://").rpartition(":")
    host = host.strip("[]")
    if not host or not port.isdecimal() or not 0 < int(port) < 65536:
        raise ValueError(f"--address {address!r} is not a Ray address: {expected}")
    try:
        socket.create_connection((host, int(port)), timeout=RAY_CONNECT_TIMEOUT).close()
    except OSError as error:
        reason = error.strerror or type(error).__name__
        raise ValueError(
            f"--address {address}: no Ray cluster answers there ({reason}); start one with "
            f"`ray start --head` or check the address"
        ) from None


def join_ray(address: str | None, cpus: int) -> bool:
    """Start a local Ray of `cpus` CPUs, or join the cluster at `address`, unless Ray is
    up already; whether this call started it (and should shut it down).
    `ConnectionError` if Ray cannot start or be joined, `ValueError` if it is not installed."""
    ray = import_ray()

    if ray.is_initialized():
        return False
    try:
        ray.init(
            address=address,
            include_dashboard=False,
            log_to_driver=False,
            configure_logging=False,
            **({} if address else {"num_cpus": cpus}),
        )
    except (ConnectionError, ValueError, RuntimeError) as error:
        raise ConnectionError(f"cannot start or join Ray: {str(error)[:300]}") from None
    return True


class _RayWorker:
    """A Ray actor: one `LockstepPlayer`, kept between episodes like a local worker."""

    def __init__(self, runner: LockstepPlayer | Players) -> None:
        keep_freed_memory()
        self.runner = runner

    def play(self, index: int, task: TaskSpec, seeds: tuple[int, ...]) -> list[PlayedEpisode]:
        return self.runner.play(task, seeds)


def run_ray(
    runner: LockstepPlayer | Players,
    jobs: Sequence[Job],
    workers: int,
    on_result: OnResult,
    address: str | None = None,
) -> list[Results]:
    """Run `jobs` as tasks of `workers` Ray actors, on a local Ray or the cluster at
    `address`. Ray restarts a dead actor and retries its task once."""
    ray = import_ray()
    from ray.exceptions import RayActorError  # lazy: ray

    started = join_ray(address, workers)
    worker_class = ray.remote(num_cpus=1, max_restarts=ATTEMPTS - 1, max_task_retries=1)(_RayWorker)
    results: list[Results] = [None] * len(jobs)
    pending = deque((index, *job) for index, job in enumerate(jobs))
    idle = [worker_class.remote(runner) for _ in range(min(workers, len(jobs)))]
    busy = {}  # future -> (actor, job)
    try:
        while pending or busy:
            while idle and pending:
                actor, job = idle.pop(), pending.popleft()
                busy[actor.play.remote(*job)] = (actor, job)
            [future], _ = ray.wait(list(busy), num_returns=1)
            actor, job = busy.pop(future)
            try:
                result = ray.get(future)
                idle.append(actor)
            except RayActorError:  # died, was restarted, and died again on the retry
                result = None
                idle.append(worker_class.remote(runner))
            results[job[0]] = result
            on_result(job[0], result)
    finally:
        if started:
            ray.shutdown()
    return results

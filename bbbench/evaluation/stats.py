"""Aggregate scores as rliable does: IQM and stratified-bootstrap confidence intervals.

Implemented here with numpy and a fixed seed (rliable resamples with numpy's
global generator, and its pinned dependencies break on pandas 3). The method
is rliable's `get_interval_estimates`: resample each task's episodes with
replacement, independently per task (the strata), compute the statistic on
the resampled scores, and take the 2.5th and 97.5th percentiles over
resamples. Each interval uses a fresh generator with the same seed, so a task's
interval depends on its own scores only, not on which other tasks ran.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
from collections.abc import Callable, Sequence

import numpy as np

BOOTSTRAP_SEED = 0
BOOTSTRAP_REPS = 10_000  # rliable's default is 50,000; 10,000 moves the bounds by < 1%
CONFIDENCE = 0.95
_CHUNK = 2_000  # resamples per batch: bounds memory on long runs


def method() -> dict[str, object]:
    """How the intervals are computed, as the documents that carry them record it."""
    return {
        "interval": "percentile, stratified bootstrap (rliable)",
        "confidence": CONFIDENCE,
        "reps": BOOTSTRAP_REPS,
        "seed": BOOTSTRAP_SEED,
    }


def iqm(scores: np.ndarray, axis: int = -1) -> np.ndarray | float:
    """Interquartile mean: the mean of the middle half (scipy's trim_mean(x, 0.25))."""
    scores = np.sort(np.asarray(scores, dtype=np.float64), axis=axis)
    n = scores.shape[axis]
    cut = int(0.25 * n)
    middle = np.take(scores, np.arange(cut, n - cut), axis=axis)
    result = middle.mean(axis=axis)
    return float(result) if np.ndim(result) == 0 else result


def mean(scores: np.ndarray, axis: int = -1) -> np.ndarray | float:
    result = np.asarray(scores, dtype=np.float64).mean(axis=axis)
    return float(result) if np.ndim(result) == 0 else result


def stratified_bootstrap_ci(
    strata: Sequence[np.ndarray],
    statistic: Callable[..., np.ndarray | float],
    reps: int = BOOTSTRAP_REPS,
    confidence: float = CONFIDENCE,
    seed: int = BOOTSTRAP_SEED,
) -> tuple[float, float]:
    """The percentile interval of `statistic` over the pooled scores of all strata.

    `statistic(x, axis=-1)` reduces the last axis. Each stratum (a task's
    episodes) is resampled with replacement keeping its size.
    """
    strata = [np.asarray(s, dtype=np.float64).ravel() for s in strata]
    if not strata or any(s.size == 0 for s in strata):
        raise ValueError("every stratum needs at least one score")
    if reps < 1 or not 0.0 < confidence < 1.0:
        raise ValueError(f"reps >= 1 and 0 < confidence < 1 required, got {reps}, {confidence}")
    values = [
        statistic(
            np.concatenate([s[i] for s, i in zip(strata, chunk, strict=True)], axis=1), axis=-1
        )
        for chunk in _resamples(tuple(s.size for s in strata), reps, seed)
    ]
    tail = (1.0 - confidence) / 2.0
    low, high = np.quantile(np.concatenate(values), [tail, 1.0 - tail])
    return float(low), float(high)


@functools.lru_cache(maxsize=8)
def _resamples(sizes: tuple[int, ...], reps: int, seed: int) -> list[list[np.ndarray]]:
    """Per chunk of resamples, per stratum, the indices drawn: they depend on the strata's
    sizes and the seed alone, so the board's thousands of intervals on strata of the same
    sizes draw them once."""
    rng = np.random.default_rng(seed)
    chunks = []
    for start in range(0, reps, _CHUNK):
        count = min(_CHUNK, reps - start)
        chunks.append([rng.integers(size, size=(count, size)).astype(np.int32) for size in sizes])
    for chunk in chunks:
        for indices in chunk:
            indices.flags.writeable = False  # shared by every caller
    return chunks


def probability_of_improvement(x_strata: Sequence[np.ndarray], y_strata: Sequence[np.ndarray]):
    """rliable's P(X > Y): per task (stratum), the probability that an episode of X scores
    above an episode of Y, ties counting half (the Mann-Whitney U over n * m); averaged
    over tasks. Returns the point estimate and its stratified-bootstrap interval, X's and
    Y's episodes resampled independently (rliable's `StratifiedIndependentBootstrap`)."""
    if len(x_strata) != len(y_strata) or not x_strata:
        raise ValueError("X and Y need scores on the same, non-empty list of tasks")
    comparisons = [_wins(x, y) for x, y in zip(x_strata, y_strata, strict=True)]
    point = float(np.mean([c.mean() for c in comparisons]))
    values = np.zeros(BOOTSTRAP_REPS)
    counts = _paired_counts(tuple(wins.shape for wins in comparisons))
    for wins, (x_counts, y_counts) in zip(comparisons, counts, strict=True):
        n, m = wins.shape
        values += np.einsum("rn,rn->r", x_counts @ wins, y_counts) / (n * m)
    values /= len(comparisons)
    tail = (1.0 - CONFIDENCE) / 2.0
    low, high = np.quantile(values, [tail, 1.0 - tail])
    return point, (float(low), float(high))


@functools.lru_cache(maxsize=2)
def _paired_counts(shapes: tuple[tuple[int, int], ...]) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per task, how often each of X's and Y's episodes is drawn in each resample (then P
    of a resample is a weighted mean of the comparison matrix, one matrix product for all
    resamples): they depend on the numbers of episodes alone, so a board's comparisons of
    entries with as many episodes draw them once."""
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    counts = []
    for n, m in shapes:
        x_counts = _draw_counts(rng, n, BOOTSTRAP_REPS)
        y_counts = _draw_counts(rng, m, BOOTSTRAP_REPS)
        x_counts.flags.writeable = y_counts.flags.writeable = False  # shared by every caller
        counts.append((x_counts, y_counts))
    return counts


def _wins(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """S[i, j] = 1 if x_i > y_j, 0.5 if equal, 0 if less."""
    x = np.asarray(x, dtype=np.float64).ravel()[:, None]
    y = np.asarray(y, dtype=np.float64).ravel()[None, :]
    if x.size == 0 or y.size == 0:
        raise ValueError("every stratum needs at least one score")
    return (x > y) + 0.5 * (x == y)


def _draw_counts(rng: np.random.Generator, size: int, reps: int) -> np.ndarray:
    """(reps, size): how many times each of `size` items is drawn, `size` draws with
    replacement per resample."""
    draws = rng.integers(size, size=(reps, size)) + size * np.arange(reps)[:, None]
    return np.bincount(draws.ravel(), minlength=reps * size).reshape(reps, size).astype(float)


# A method is its runs (training seeds): rliable's protocol, with every episode counted.
RANKED_RUNS = 3  # a learned method with fewer runs is listed, not ranked
IQM_RUNS = 5  # from this many runs the point estimate is the IQM over runs x tasks
METHOD_RULE = (
    "a run's score on a task is its mean normalized score over every evaluation episode, "
    "falls included; a method's score is the mean over its runs x tasks, or their IQM "
    f"(the mean of the middle half) from {IQM_RUNS} runs on; its 95% interval is a "
    "two-level stratified bootstrap: per task, runs drawn with replacement, then each drawn "
    "run's episodes; P(X > Y) is the probability that a run of X scores above a run of Y "
    "on a task (ties half), averaged over tasks, with its interval from the same bootstrap"
)


@dataclasses.dataclass(frozen=True)
class Runs:
    """A method's normalized episode scores on a set of tasks: per task, an array of shape
    (runs, episodes), the same runs in the same order on every task."""

    scores: tuple[np.ndarray, ...]
    seed: int = BOOTSTRAP_SEED  # the method's own draws (`method_seed`)
    # reps -> the resampled run scores, drawn once and reused by every comparison
    _draws: dict[int, np.ndarray] = dataclasses.field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    def __post_init__(self) -> None:
        if not self.scores:
            raise ValueError("a method needs scores on at least one task")
        shapes = [np.shape(task) for task in self.scores]
        if any(len(shape) != 2 or 0 in shape for shape in shapes):
            raise ValueError(f"each task's scores are (runs, episodes), got shapes {shapes}")
        if len({shape[0] for shape in shapes}) != 1:
            raise ValueError(f"every task needs the same runs, got shapes {shapes}")

    @property
    def runs(self) -> int:
        return np.shape(self.scores[0])[0]

    def run_scores(self) -> np.ndarray:
        """(runs, tasks): each run's mean over its episodes of each task."""
        return np.stack(
            [np.asarray(task, dtype=np.float64).mean(axis=1) for task in self.scores], 1
        )

    def point(self) -> float:
        return float(_aggregate(self.run_scores()[None])[0])

    def resampled(self, reps: int = BOOTSTRAP_REPS) -> np.ndarray:
        """(reps, runs, tasks): the run scores of `reps` two-level resamples."""
        if reps not in self._draws:
            self._draws[reps] = _resampled_run_scores(self, reps)
        return self._draws[reps]

    def interval(self, reps: int = BOOTSTRAP_REPS) -> tuple[float, float]:
        return _percentiles(_aggregate(self.resampled(reps)))


def method_seed(name: str) -> int:
    """The seed of a method's bootstrap draws, from its name: the draws of two methods are
    independent, and neither depends on which other methods are on the board."""
    return int.from_bytes(hashlib.sha256(name.encode()).digest()[:8], "little")


def _aggregate(run_scores: np.ndarray) -> np.ndarray:
    """(reps, runs, tasks) -> (reps,): the mean over runs x tasks, or the IQM from
    `IQM_RUNS` runs on."""
    flat = run_scores.reshape(run_scores.shape[0], -1)
    return iqm(flat, axis=-1) if run_scores.shape[1] >= IQM_RUNS else flat.mean(axis=-1)


def _percentiles(values: np.ndarray) -> tuple[float, float]:
    tail = (1.0 - CONFIDENCE) / 2.0
    low, high = np.quantile(values, [tail, 1.0 - tail])
    return float(low), float(high)


def _resampled_run_scores(method: Runs, reps: int) -> np.ndarray:
    """Per task, runs drawn with replacement, then each drawn run's episodes; from the
    method's own seed, so the draws depend on nothing else on the board."""
    rng = np.random.default_rng(method.seed)
    tasks = []
    for task in method.scores:
        task = np.asarray(task, dtype=np.float64)
        runs, episodes = task.shape
        means = np.empty((reps, runs))
        for start in range(0, reps, _CHUNK):
            count = min(_CHUNK, reps - start)
            drawn_runs = rng.integers(runs, size=(count, runs))
            drawn_episodes = rng.integers(episodes, size=(count, runs, episodes))
            means[start : start + count] = task[drawn_runs[..., None], drawn_episodes].mean(-1)
        tasks.append(means)
    resampled = np.stack(tasks, axis=2)
    resampled.flags.writeable = False
    return resampled


def run_improvement(
    x: Runs, y: Runs, reps: int = BOOTSTRAP_REPS
) -> tuple[float, tuple[float, float]]:
    """P(X > Y) over runs: per task, the probability that a run of X scores above a run of
    Y (ties half), averaged over tasks; with its interval from each method's two-level
    resamples (drawn independently, from each method's own seed)."""
    if len(x.scores) != len(y.scores):
        raise ValueError("X and Y need scores on the same tasks")
    point = float(_run_wins(x.run_scores()[None], y.run_scores()[None])[0])
    return point, _percentiles(_run_wins(x.resampled(reps), y.resampled(reps)))


def _run_wins(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(reps, runs_x, tasks) and (reps, runs_y, tasks) -> (reps,)."""
    upper, lower = x[:, :, None, :], y[:, None, :, :]
    wins = (upper > lower) + 0.5 * (upper == lower)
    return wins.mean(axis=(1, 2, 3))


def ranks(beaten_by: dict[str, list[str]]) -> dict[str, int]:
    """Ranks that do not chain: a method's rank is 1 plus the number of methods that beat
    it (`beaten_by[m]`: the methods whose P(other > m) has its interval above 0.5)."""
    return {name: 1 + len(others) for name, others in beaten_by.items()}

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

import functools
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

"""Arithmetic that gives the same bits on every x86-64 CPU.

numpy chooses SIMD code at run time by CPU: `np.exp` and `np.tanh` round
differently on AVX-512, AVX2 and older machines (no AVX2: libm's functions), and
`@` calls a BLAS kernel picked per CPU that sums in another order. The
leaderboard is re-scored on whatever machine CI runs on and compared byte for
byte, so what decides an episode (the terrain, a policy's network) is built here
from operations IEEE 754 rounds exactly (+, -, *, /, comparisons, `rint`,
`ldexp`), in an order that does not depend on the CPU.

Measured: on a machine without AVX2, a stored SAC episode played from the
numpy `@` and `np.tanh` of an AVX-512 machine took other actions from the first
step (docs/tasks.md, "The same episode on every machine").
"""

from __future__ import annotations

import math

import numpy as np

_LN2_HIGH, _LN2_LOW = 0.6931471803691238, 1.9082149292705877e-10  # ln 2 = high + low
_TAYLOR_TERMS = 14  # |r| <= ln(2) / 2: the next term is under 1e-17
# 1/n! for n = 10..1, for `_exp_float32`'s Horner steps (|r| <= ln 2 / 2: the r**11
# term is under 1e-12, far below float32's resolution).
_SHORT_TAYLOR = tuple(1.0 / math.factorial(n) for n in range(10, 0, -1))


def exp(x: np.ndarray) -> np.ndarray:
    """e**x (float64) from +, *, / and ldexp only, to a few units in the last place of
    `np.exp`: x = k ln 2 + r, a Taylor polynomial of r (Horner), scaled by 2**k."""
    x = np.clip(np.asarray(x, dtype=np.float64), -746.0, 709.0)
    k = np.rint(x / (_LN2_HIGH + _LN2_LOW))
    r = (x - k * _LN2_HIGH) - k * _LN2_LOW
    result = np.ones_like(r)
    for n in range(_TAYLOR_TERMS - 1, 0, -1):
        result = 1.0 + result * r / n
    return np.ldexp(result, k.astype(np.int64))


def _expm1_parts(x) -> tuple[np.ndarray, np.ndarray]:
    """(p, k) with e**x = 2**k (1 + p) and p = e**r - 1 for |r| <= ln 2 / 2, in float64,
    accurate to ~1e-12 relative (p too, near x = 0): enough for float32 results, with
    fewer steps than `exp` (a network's activations run every step)."""
    x = np.clip(np.asarray(x, dtype=np.float64), -104.0, 89.0)  # float32's range
    k = np.rint(x * (1.0 / (_LN2_HIGH + _LN2_LOW)))
    r = x - k * _LN2_HIGH
    r -= k * _LN2_LOW
    p = np.full_like(r, _SHORT_TAYLOR[0])
    for coefficient in _SHORT_TAYLOR[1:]:
        p *= r
        p += coefficient
    p *= r
    return p, k.astype(np.int32)


def exp32(x: np.ndarray) -> np.ndarray:
    """e**x of a float32 array, float32 (correctly rounded on 10**6 samples; numpy's own
    float32 `exp` was off by up to 2 units in the last place on 39% of them)."""
    p, k = _expm1_parts(x)
    p += 1.0
    return np.ldexp(p, k).astype(np.float32)


def _expm1(x) -> np.ndarray:
    p, k = _expm1_parts(x)
    return np.ldexp(p, k) + (np.ldexp(1.0, k) - 1.0)


def expm1(x: np.ndarray) -> np.ndarray:
    """e**x - 1 of a float32 array, float32."""
    return _expm1(x).astype(np.float32)


def tanh(x: np.ndarray) -> np.ndarray:
    """tanh of a float32 array, float32: (e**2x - 1) / (e**2x + 1), exact in sign, tiny
    values included (correctly rounded on 10**6 samples)."""
    m = _expm1(np.multiply(x, 2.0, dtype=np.float64))
    t = m / (m + 2.0)
    return np.copysign(t, x, dtype=np.float64).astype(np.float32)


def sigmoid(x: np.ndarray) -> np.ndarray:
    """1 / (1 + e**-x) of a float32 array, float32."""
    p, k = _expm1_parts(np.negative(x, dtype=np.float64))
    p += 1.0
    e = np.ldexp(p, k)
    e += 1.0
    return np.divide(1.0, e).astype(np.float32)


def matmul(x: np.ndarray, weight_t: np.ndarray) -> np.ndarray:
    """`x @ weight_t` for x of shape (k, n) and weight_t (n, m), summed in one fixed order.

    Each product is rounded once (an elementwise multiply), and the n products of an
    output are added in an order fixed by numpy's code, not by the CPU: over a middle
    axis numpy adds whole slices one after another (in index order), and over the
    last one (m = 1) it sums pairwise with eight fixed accumulators, whatever the
    vector width. BLAS kernels split and reorder the sum by the CPU's vector width.
    """
    return np.add.reduce(x[:, :, None] * weight_t, axis=1)

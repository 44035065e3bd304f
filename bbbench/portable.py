"""Arithmetic that gives the same bits on every x86-64 CPU.

numpy chooses SIMD code at run time by CPU: `np.exp` and `np.tanh` round
differently on AVX-512, AVX2 and older machines (no AVX2: libm's functions), and
`@` calls a BLAS kernel picked per CPU that sums in another order. The
leaderboard is re-scored on whatever machine CI runs on and compared byte for
byte, so what decides an episode (the terrain, a policy's network) is defined
here by its value, not by the machine:

- a network layer (`Layer`) and `tanh` return, for each output, the float32
  nearest the exact value: fast float64 arithmetic with a bound on its error
  settles almost every output, and the rare one near a float32 halfway point is
  computed exactly;
- `exp` (the terrain's kernel) and the rarer activations (`exp32`, `expm1`,
  `sigmoid`) use only operations IEEE 754 rounds exactly (+, -, *, /, `rint`,
  `ldexp`), in a fixed order;
- `dot3`, the dot product of two 3-vectors, as OpenBLAS's default kernels compute it
  (which `np.dot` and `np.linalg.norm` call, and `OPENBLAS_CORETYPE=Haswell` replaces
  with another rounding), each fused multiply-add computed exactly;
- `total`, a sum of Python numbers added left to right: the built-in `sum` of floats
  is compensated from Python 3.12 on (Neumaier's algorithm), so `sum([0.1] * 10)` is
  0.9999999999999999 on 3.11 and 1.0 on 3.12. bbbench calls `total`, never `sum`
  (tests/test_portable.py holds the package to it), and its sums are the same bits on
  Python 3.10 to 3.13.

Measured: on a machine without AVX2, a stored SAC episode played from the
numpy `@` and `np.tanh` of an AVX-512 machine took other actions from the first
step (docs/notebook.md, "The same episode on every machine").
"""

from __future__ import annotations

import decimal
import math
from collections.abc import Iterable

import numpy as np

_LN2_HIGH, _LN2_LOW = 0.6931471803691238, 1.9082149292705877e-10  # ln 2 = high + low
_TAYLOR_TERMS = 14  # |r| <= ln(2) / 2: the next term is under 1e-17
# 1/n! for n = 10..1, for `_expm1_parts`'s Horner steps (|r| <= ln 2 / 2: the r**11
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


def _exp64(x) -> np.ndarray:
    p, k = _expm1_parts(x)
    p += 1.0
    return np.ldexp(p, k)


def exp32(x: np.ndarray) -> np.ndarray:
    """e**x of a float32 array, float32 (correctly rounded on 10**6 samples; numpy's own
    float32 `exp` was off by up to 2 units in the last place on 39% of them)."""
    return _exp64(x).astype(np.float32)


def expm1(x: np.ndarray) -> np.ndarray:
    """e**x - 1 of a float32 array, float32."""
    p, k = _expm1_parts(x)
    return (np.ldexp(p, k) + (np.ldexp(1.0, k) - 1.0)).astype(np.float32)


def sigmoid(x: np.ndarray) -> np.ndarray:
    """1 / (1 + e**-x) of a float32 array, float32."""
    e = _exp64(np.negative(x, dtype=np.float64))
    e += 1.0
    return np.divide(1.0, e).astype(np.float32)


_UNIT = 2.0**-53  # float64's unit roundoff
# How far numpy's float64 tanh may be from the exact one, relative (64 units in the
# last place of float64; within a few on any CPU).
_TANH_ERROR = 2.0**-46


class Layer:
    """`x @ weight_t + bias` for float32 x of shape (k, n): each output the float32
    nearest the exact value, which no CPU, BLAS or numpy version can change.

    The fast path multiplies in float64 with BLAS (a product of two float32 is exact
    in float64, so only the sum rounds, by at most (n + 1) units of roundoff times the
    sum of the terms' sizes, whatever the order or the FMAs) and keeps an output when
    both ends of that error interval round to the same float32. The rest (about one
    output in ten million) is summed exactly (`math.fsum`) and rounded once.
    """

    def __init__(self, weight_t: np.ndarray, bias: np.ndarray) -> None:
        self.weight = np.asarray(weight_t, dtype=np.float64)
        self.bias = np.asarray(bias, dtype=np.float64)
        # The error bound per unit of |x|, and the bias's share: the terms' sizes times
        # (n + 2) units of roundoff, twice over for the rounding of the bound itself.
        slack = 2.0 * (self.weight.shape[0] + 2) * _UNIT
        self.size = np.abs(self.weight) * slack
        self.bias_size = np.abs(self.bias) * slack
        self._slack = slack
        # For `error`: the largest sum of |weights| into one output, and the largest |bias|.
        self._gain = float(np.abs(self.weight).sum(axis=0).max(initial=0.0))
        self._bias_max = float(np.abs(self.bias).max(initial=0.0))

    def __call__(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        y = self.float64(x)
        bound = np.abs(x) @ self.size
        bound += self.bias_size
        return _settle(y, bound, lambda i, j: exact_dot(x[i], self.weight[:, j], self.bias[j]))

    def float64(self, x: np.ndarray) -> np.ndarray:
        """`x @ weight + bias` for float64 x, in float64 (BLAS, no rounding to float32):
        the fast pass that `__call__` settles and `error` bounds."""
        y = x @ self.weight
        y += self.bias
        return y

    def error(self, input_max: float, input_error: float, output_max: float | None = None) -> float:
        """A bound on how far `x @ weight + bias`, computed in float64 with no rounding to
        float32, can be from this layer's output (`self(X)`) for every output, when the
        float32 input X the layer is defined on is within `input_error` of x and
        |x| <= `input_max`.

        The sum's rounding (at most `slack` times the terms' sizes), what the input's
        error can move (at most the largest sum of |weights| into one output, times it),
        and the last rounding to float32 (2**-24 of the exact value: at most
        `output_max`, the largest |output| of the float64 pass, plus the two above, or
        else the largest sum of |weights| times |X| plus the largest |bias|; 2**-150
        near zero); and 2**-20 of it, for the rounding of this bound itself.
        """
        gain, bias_max = self._gain, self._bias_max
        moved = self._slack * (gain * input_max + bias_max) + gain * input_error
        if output_max is None:
            reach = gain * (input_max + input_error) + bias_max
        else:
            reach = output_max + moved
        return (1.0 + 2.0**-20) * (moved + 2.0**-24 * reach + 2.0**-149)


def tanh_error(input_error: float) -> float:
    """A bound on |np.tanh(y) - `tanh`(Y)| (float64 estimate against the float32 defined
    value) when |y - Y| <= `input_error`: tanh moves by no more than its argument, numpy's
    float64 tanh is within `_TANH_ERROR` of the exact one (as `tanh`), and the result
    rounds to float32 (|tanh| <= 1)."""
    moved = input_error + _TANH_ERROR
    return (1.0 + 2.0**-20) * (moved + 2.0**-24 * (1.0 + moved) + 2.0**-149)


def tanh(x: np.ndarray) -> np.ndarray:
    """tanh of a float32 array: each value the float32 nearest the exact tanh.

    numpy's float64 `tanh` (within a few units in the last place on any CPU) settles
    all but about one value in ten million; those are computed to 80 digits.
    """
    y = np.tanh(np.asarray(x, dtype=np.float64))
    bound = np.abs(y)
    bound *= _TANH_ERROR
    settled = _settle(y, bound, lambda *index: exact_tanh(float(x[index])))
    return np.copysign(settled, y, out=settled)  # -0.0 stays -0.0


def _settle(y: np.ndarray, bound: np.ndarray, exact) -> np.ndarray:
    """float32 of y where every value within `bound` of it rounds alike; `exact(*index)`
    elsewhere (NaN and infinities pass through)."""
    low = (y - bound).astype(np.float32)
    result = (y + bound).astype(np.float32)
    unsettled = low != result
    if unsettled.any():
        for index in zip(*np.nonzero(unsettled & np.isfinite(y)), strict=True):
            result[index] = exact(*index)
        loose = unsettled & ~np.isfinite(y)
        result[loose] = y[loose]
    return result


def _nearest_float32(value: float, above) -> np.float32:
    """The float32 nearest a real number whose float64 rounding is `value`; `above()`
    tells (by its sign) on which side of `value` the number lies, asked only when
    `value` is halfway between two float32."""
    first = np.float32(value)
    if float(first) == value:
        return first
    low = first if float(first) < value else np.nextafter(first, np.float32(-np.inf))
    high = np.nextafter(low, np.float32(np.inf))
    middle = (float(low) + float(high)) / 2.0  # exact: float32 halves fit in float64
    if value != middle:
        return low if value < middle else high
    side = above()
    return first if side == 0 else (high if side > 0 else low)


def exact_dot(x: np.ndarray, weight: np.ndarray, bias: float) -> np.float32:
    terms = [*(x * weight).tolist(), float(bias)]  # each product exact in float64
    value = math.fsum(terms)
    return _nearest_float32(value, lambda: math.fsum([*terms, -value]))


def exact_tanh(value: float) -> np.float32:
    with decimal.localcontext() as context:
        context.prec = 80
        e = (decimal.Decimal(value) * 2).exp()
        exact = (e - 1) / (e + 1)
        return _nearest_float32(float(exact), lambda: exact - decimal.Decimal(float(exact)))


def dot3(x, y) -> float:
    """x . y for 3-vectors, as OpenBLAS's default x86-64 kernels (SkylakeX, Zen) compute
    it for three values, `fma(x2, y2, fma(x1, y1, x0 * y0))`, on every CPU.

    `np.dot` of float64 vectors calls BLAS, whose kernel numpy's OpenBLAS picks by CPU:
    the Haswell kernel (`OPENBLAS_CORETYPE=Haswell`, set on some machines) rounds each
    product, the default ones fuse them; over an episode of Convoy-v0's tethers the two
    part in the last bits, then in whole steps. Its published episodes were played with
    the fused sums: this is that arithmetic, with each fused multiply-add exact
    (`fused_multiply_add`).
    """
    x0, x1, x2 = (float(value) for value in x)
    y0, y1, y2 = (float(value) for value in y)
    return fused_multiply_add(x2, y2, fused_multiply_add(x1, y1, x0 * y0))


def fused_multiply_add(a: float, b: float, c: float) -> float:
    """a * b + c rounded once (C's `fma`; `math.fma` arrives in Python 3.13): the product
    split exactly into two floats (Dekker's product, Veltkamp's split), then the three
    summed with one rounding (`math.fsum`). Exact for finite values away from overflow
    (|a|, |b| < 2**995) and underflow."""
    product = a * b
    a_high, a_low = _split(a)
    b_high, b_low = _split(b)
    error = ((a_high * b_high - product) + a_high * b_low + a_low * b_high) + a_low * b_low
    return math.fsum((product, error, c))


def _split(value: float) -> tuple[float, float]:
    """Veltkamp's split: value = high + low, each with at most 26 significant bits."""
    scaled = 134217729.0 * value  # 2**27 + 1
    high = scaled - (scaled - value)
    return high, value - high


def total(values: Iterable, start=0):
    """`start` plus each of `values`, added left to right: what Python 3.11's built-in
    `sum` returns, on every Python (3.12's `sum` of floats is compensated and differs in
    the last bit). Exact for ints and bools."""
    result = start
    for value in values:
        result += value
    return result

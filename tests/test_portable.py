"""bbbench.portable: arithmetic that decides an episode gives the same bits on every CPU."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bbbench import portable

ROOT = Path(__file__).resolve().parents[1]
SUBMISSIONS = ROOT / "leaderboards" / "submissions"


def _ulps(ours: np.ndarray, reference: np.ndarray) -> np.ndarray:
    return np.abs(ours.view(np.int32).astype(np.int64) - reference.view(np.int32).astype(np.int64))


@pytest.fixture(scope="module")
def samples() -> np.ndarray:
    rng = np.random.default_rng(7)
    spread = (rng.standard_normal(200_000) * 4).astype(np.float32)
    tiny = (rng.standard_normal(20_000) * 1e-6).astype(np.float32)
    edges = np.float32([0.0, 1e-30, -1e-30, 9.5, -9.5, 60.0, -60.0, 88.0, -88.0])
    return np.concatenate([spread, tiny, edges])


@pytest.mark.parametrize(
    ("ours", "exact"),
    [(portable.tanh, np.tanh), (portable.exp32, np.exp), (portable.expm1, np.expm1)],
)
def test_functions_round_as_float64_rounded_to_float32(samples, ours, exact):
    """Within one unit in the last place of the float64 value rounded to float32 (in
    practice equal: numpy's own float32 tanh and exp miss it by 1-2 units)."""
    reference = exact(samples.astype(np.float64)).astype(np.float32)
    result = ours(samples)
    assert result.dtype == np.float32
    assert _ulps(result, reference).max() <= 1


def test_tanh_keeps_the_sign_of_zero():
    assert np.signbit(portable.tanh(np.float32([-0.0])))[0]
    assert not np.signbit(portable.tanh(np.float32([0.0])))[0]


@pytest.mark.parametrize("outputs", [1, 9, 64])
@pytest.mark.parametrize("batch", [1, 8])
def test_matmul_adds_the_products_in_a_fixed_order(batch, outputs):
    """Every product rounded once, then summed as numpy's code fixes it: in index order over
    a middle axis, pairwise (eight accumulators) when there is one output."""
    rng = np.random.default_rng(batch * 100 + outputs)
    x = rng.standard_normal((batch, 64)).astype(np.float32)
    weight_t = rng.standard_normal((64, outputs)).astype(np.float32)
    result = portable.matmul(x, weight_t)
    assert result.dtype == np.float32
    assert result.shape == (batch, outputs)
    products = x[:, :, None] * weight_t
    if outputs > 1:  # one slice after another
        expected = products[:, 0, :].copy()
        for k in range(1, 64):
            expected = expected + products[:, k, :]
        np.testing.assert_array_equal(result, expected)
    np.testing.assert_allclose(result, x.astype(np.float64) @ weight_t, rtol=1e-4, atol=1e-4)


def test_matmul_does_not_depend_on_the_batch():
    """A row's output is the same alone or among others (lockstep groups of any size)."""
    rng = np.random.default_rng(3)
    x = rng.standard_normal((8, 17)).astype(np.float32)
    weight_t = rng.standard_normal((17, 64)).astype(np.float32)
    together = portable.matmul(x, weight_t)
    for i in range(8):
        np.testing.assert_array_equal(portable.matmul(x[i : i + 1], weight_t)[0], together[i])


_ACT = """
import json, sys
import numpy as np
from bbbench.leaderboard.submissions import read_submission
from pathlib import Path
rng = np.random.default_rng(11)
out = {}
for slug in sys.argv[1:]:
    policy = read_submission(Path(slug)).load_policy()
    actor = policy.actor("bbbench/VelocityTracking-v0")
    observations = rng.uniform(-1, 1, (8, 5)).astype(np.float32)
    out[slug] = np.asarray(actor(observations), dtype=np.float64).tobytes().hex()
print(json.dumps(out))
"""


def test_networks_act_the_same_whatever_simd_and_blas_numpy_picks():
    """A SAC (ReLU, tanh-squashed) and a PPO (tanh) submission act with the same bits when
    numpy's SIMD paths and OpenBLAS's kernel are forced to the oldest ones."""
    slugs = [str(SUBMISSIONS / "sac-flatbalance-v0-s0"), str(SUBMISSIONS / "ppo-reference")]
    features = np.__config__.CONFIG["SIMD Extensions"]["found"]  # dispatched beyond baseline
    runs = []
    for extra in ({}, {"NPY_DISABLE_CPU_FEATURES": " ".join(features),
                       "OPENBLAS_CORETYPE": "Prescott"}):  # fmt: skip
        done = subprocess.run(
            [sys.executable, "-c", _ACT, *slugs],
            capture_output=True,
            text=True,
            check=True,
            env={**os.environ, **extra},
        )
        runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
    assert runs[0] == runs[1]

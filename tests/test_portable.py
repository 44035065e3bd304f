"""bbbench.portable: arithmetic that decides an episode gives the same bits on every CPU."""

from __future__ import annotations

import ast
import itertools
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bbbench import portable
from bbbench.evaluation.results import read
from bbbench.policies.mlp import MlpActor

ROOT = Path(__file__).resolve().parents[1]


def _ulps(ours: np.ndarray, reference: np.ndarray) -> np.ndarray:
    return np.abs(ours.view(np.int32).astype(np.int64) - reference.view(np.int32).astype(np.int64))


@pytest.fixture(scope="module")
def samples() -> np.ndarray:
    rng = np.random.default_rng(7)
    spread = (rng.standard_normal(200_000) * 4).astype(np.float32)
    tiny = (rng.standard_normal(20_000) * 1e-6).astype(np.float32)
    edges = np.float32([0.0, 1e-30, -1e-30, 9.5, -9.5, 60.0, -60.0, 88.0, -88.0])
    return np.concatenate([spread, tiny, edges])


@pytest.mark.parametrize(("ours", "exact"), [(portable.exp32, np.exp), (portable.expm1, np.expm1)])
def test_functions_round_as_float64_rounded_to_float32(samples, ours, exact):
    """Within one unit in the last place of the float64 value rounded to float32 (in
    practice equal: numpy's own float32 exp misses it by 1-2 units)."""
    reference = exact(samples.astype(np.float64)).astype(np.float32)
    result = ours(samples)
    assert result.dtype == np.float32
    assert _ulps(result, reference).max() <= 1


def test_tanh_is_the_nearest_float32(samples):
    """The fast path agrees with 80-digit tanh rounded once, on every sample checked."""
    result = portable.tanh(samples)
    assert result.dtype == np.float32
    picks = np.random.default_rng(0).choice(len(samples), 3000, replace=False)
    for i in [*picks, *range(len(samples) - 9, len(samples))]:
        assert result[i] == portable.exact_tanh(float(samples[i])), samples[i]


def test_tanh_keeps_the_sign_of_zero():
    assert np.signbit(portable.tanh(np.float32([-0.0])))[0]
    assert not np.signbit(portable.tanh(np.float32([0.0])))[0]


@pytest.mark.parametrize("outputs", [1, 9, 64])
@pytest.mark.parametrize("batch", [1, 8])
def test_layer_gives_the_float32_nearest_the_exact_value(batch, outputs):
    rng = np.random.default_rng(batch * 100 + outputs)
    x = rng.standard_normal((batch, 64)).astype(np.float32)
    weight_t = rng.standard_normal((64, outputs)).astype(np.float32)
    bias = rng.standard_normal(outputs).astype(np.float32)
    result = portable.Layer(weight_t, bias)(x)
    assert result.dtype == np.float32
    assert result.shape == (batch, outputs)
    x64, w64 = x.astype(np.float64), weight_t.astype(np.float64)
    for i in range(batch):
        for j in range(outputs):
            assert result[i, j] == portable.exact_dot(x64[i], w64[:, j], float(bias[j]))


def test_halfway_values_round_by_what_lies_beyond_them():
    """Sums whose float64 rounding falls exactly halfway between two float32: the exact
    remainder decides, ties go to even."""
    one, step = 1.0, 2.0**-24  # halfway between 1 and the next float32
    assert portable.exact_dot(np.array([one, step]), np.ones(2), 0.0) == np.float32(1.0)
    beyond = portable.exact_dot(np.array([one, step, 2.0**-80]), np.ones(3), 0.0)
    assert beyond == np.nextafter(np.float32(1.0), np.float32(2.0))
    below = portable.exact_dot(np.array([one, step, -(2.0**-80)]), np.ones(3), 0.0)
    assert below == np.float32(1.0)


def test_layer_settles_unsure_outputs_exactly():
    """An output next to a float32 halfway point leaves the fast path and is summed
    exactly (the bound is wide enough to send it there)."""
    x = np.array([[1.0, 2.0**-24, 2.0**-60]], dtype=np.float32)
    weight_t = np.ones((3, 2), dtype=np.float32)
    out = portable.Layer(weight_t, np.zeros(2, dtype=np.float32))(x)
    np.testing.assert_array_equal(out, np.nextafter(np.float32(1.0), np.float32(2.0)))


def test_layer_does_not_depend_on_the_batch():
    """A row's output is the same alone or among others (lockstep groups of any size)."""
    rng = np.random.default_rng(3)
    x = rng.standard_normal((8, 17)).astype(np.float32)
    layer = portable.Layer(rng.standard_normal((17, 64)).astype(np.float32), np.zeros(64))
    together = layer(x)
    for i in range(8):
        np.testing.assert_array_equal(layer(x[i : i + 1])[0], together[i])


_ACT = """
import json, sys
import numpy as np
from bbbench.policies import load_policy
rng = np.random.default_rng(11)
out = {}
for path in sys.argv[1:]:
    actor = load_policy(path).actor("bbbench/VelocityTracking-v0")
    observations = rng.uniform(-1, 1, (8, 5)).astype(np.float32)
    out[path] = np.asarray(actor(observations), dtype=np.float64).tobytes().hex()
print(json.dumps(out))
"""


def test_networks_act_the_same_whatever_simd_and_blas_numpy_picks():
    """A SAC (ReLU, tanh-squashed) and a PPO (tanh) submission act with the same bits when
    numpy's SIMD paths and OpenBLAS's kernel are forced to the oldest ones."""
    # SAC FlatBalance-v0 (seed 0), on the board until the baselines of the new reward.
    paths = [str(ROOT / "tests" / "data" / "sac-flatbalance-v0.zip"), "reference"]
    features = np.__config__.CONFIG["SIMD Extensions"]["found"]  # dispatched beyond baseline
    runs = []
    for extra in ({}, {"NPY_DISABLE_CPU_FEATURES": " ".join(features),
                       "OPENBLAS_CORETYPE": "Prescott"}):  # fmt: skip
        done = subprocess.run(
            [sys.executable, "-c", _ACT, *paths],
            capture_output=True,
            text=True,
            check=True,
            env={**os.environ, **extra},
        )
        runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
    assert runs[0] == runs[1]


def _network(rng, activation: str, widths=(5, 64, 64, 9), scale: float = 1.0) -> MlpActor:
    layers = [
        (
            (rng.standard_normal((n, m)) * scale / np.sqrt(n)).astype(np.float32),
            (rng.standard_normal(m) * 0.1).astype(np.float32),
        )
        for n, m in itertools.pairwise(widths)
    ]
    return MlpActor(tuple(layers[:-1]), activation, layers[-1], "argmax")


@pytest.mark.parametrize("activation", ["Tanh", "ReLU"])
@pytest.mark.parametrize(("scale", "tight"), [(0.5, 1e-4), (3.0, 1e-2)])
def test_the_float64_estimate_is_within_its_bound_of_the_defined_network(activation, scale, tight):
    """The fast argmax path rests on this bound: every head output of the float64 pass
    within `error` of the network as defined (each layer's float32 nearest the exact)."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        actor = _network(rng, activation, scale=scale)
        observations = (rng.standard_normal((16, 5)) * [0.3, 3.0, 20.0, 10.0, 1.0]).astype(
            np.float32
        )
        estimate, error = actor.estimate(observations)
        defined = actor.outputs(observations).astype(np.float64)
        assert np.abs(estimate - defined).max() <= error
        # A bound, not a blow-up (larger weights amplify the worst case more).
        assert error < tight * max(1.0, np.abs(defined).max())


def test_greedy_actions_are_the_defined_networks_argmax():
    rng = np.random.default_rng(3)
    for activation in ("Tanh", "ReLU"):
        actor = _network(rng, activation)
        observations = (rng.standard_normal((4000, 5)) * 3.0).astype(np.float32)
        defined = actor.outputs(observations).argmax(axis=1).tolist()
        assert [actor(row[None])[0] for row in observations] == defined
        fast = [actor.greedy(row[None]) for row in observations]
        assert all(row == [action] for row, action in zip(fast, defined, strict=True) if row)
        assert fast.count(None) < 40  # nearly every step decided by the estimate


def test_a_tie_is_left_to_the_defined_network():
    """Two identical head rows tie exactly: the estimate cannot tell them apart, and the
    defined network's argmax (the first) decides."""
    rng = np.random.default_rng(5)
    actor = _network(rng, "Tanh")
    weight, bias = actor.head
    weight, bias = weight.copy(), bias.copy()
    weight[:, 6], bias[6] = weight[:, 2], bias[2] + 100.0
    weight[:, 3], bias[3] = weight[:, 2], bias[2] + 100.0
    tied = MlpActor(actor.hidden, "Tanh", (weight, bias), "argmax")
    observation = np.zeros((1, 5), dtype=np.float32)
    assert tied.greedy(observation) is None
    assert tied(observation) == [3]


def test_a_nan_observation_is_left_to_the_defined_network():
    actor = _network(np.random.default_rng(9), "ReLU")
    observation = np.array([[0.1, np.nan, 0.0, 0.0, 0.0]], dtype=np.float32)
    assert actor.greedy(observation) is None
    assert actor(observation) == [None]


def test_dot3_is_the_fused_sum_exactly():
    """dot3 = fma(x2, y2, fma(x1, y1, x0 y0)), each fma rounded once: against exact
    rational arithmetic, on vectors of positions (m), velocities (m/s) and their
    differences, where the fused and the plain sums often part."""
    from fractions import Fraction

    def exact_fma(a, b, c):
        return float(Fraction(a) * Fraction(b) + Fraction(c))

    rng = np.random.default_rng(0)
    parted = 0
    for scale in (1e-6, 1e-2, 1.0, 3.0, 1e3):
        for _ in range(500):
            x, y = rng.normal(size=3) * scale, rng.normal(size=3)
            expected = exact_fma(x[2], y[2], exact_fma(x[1], y[1], x[0] * y[0]))
            assert portable.dot3(x, y) == expected
            parted += expected != x[0] * y[0] + x[1] * y[1] + x[2] * y[2]
    assert parted > 100  # the plain sum (OpenBLAS's Haswell kernel) differs often


def test_total_adds_left_to_right_on_every_python():
    """The values Python 3.11's `sum` gives, recorded: 3.12's compensated `sum` returns 1.0
    for the first and 1.0 for the second."""
    assert portable.total([0.1] * 10) == 0.9999999999999999
    assert portable.total([1e16, 1.0, -1e16]) == 0.0
    assert portable.total([True, False, True]) == 2
    assert portable.total([]) == 0
    assert portable.total([0.5, 0.25], start=1.0) == 1.75


def test_the_package_never_calls_the_builtin_sum():
    """What decides a score is the same bits on Python 3.10 to 3.13: bbbench sums with
    `portable.total`, whose order no Python version changes."""
    calls = []
    for path in sorted((ROOT / "bbbench").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Name)
                and node.func.id == "sum"
            ):
                calls.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert calls == [], f"the built-in sum (use bbbench.portable.total): {calls}"


def test_no_module_that_sums_with_total_hides_it_under_a_local_name():
    """A function that assigns `total` would call its own number, not the sum."""
    hidden = []
    for path in sorted((ROOT / "bbbench").rglob("*.py")):
        tree = ast.parse(path.read_text())
        imports_total = any(
            isinstance(node, ast.ImportFrom)
            and node.module == "bbbench.portable"
            and any(alias.name == "total" for alias in node.names)
            for node in ast.walk(tree)
        )
        if not imports_total:
            continue
        for node in ast.walk(tree):
            stored = isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store)
            if stored and node.id == "total":
                hidden.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert hidden == []


@pytest.mark.parametrize("coretype", ["Haswell", None])
def test_a_convoy_episode_is_the_recorded_one_whatever_blas_kernel_runs(coretype):
    """Convoy-v0's tethers read lengths and rates with dot3, not BLAS: the team
    controller's recorded episode replays bit for bit under OpenBLAS's Haswell kernel
    (which rounds each product) and under the default one."""
    board = Path(__file__).resolve().parents[1] / "leaderboards" / "results" / "team.json"
    (block,) = [b for b in read(board)["tasks"] if b["task"].endswith("Convoy-v0")]
    # An episode whose tethers part under the Haswell kernel's rounding (measured).
    (recorded,) = [e for e in block["episodes"] if e["seed"] == 2147483658]
    code = f"""
import json
from bbbench.evaluation.episodes import LockstepPlayer
from bbbench.policies import load_policy
task = "bbbench/Convoy-v0"
player = LockstepPlayer({{task: load_policy("team").actor(task)}}, "discrete", sampled=False)
(episode,) = player.play(task, [{recorded["seed"]}])
print(json.dumps([episode.episode_return, episode.length]))
"""
    env = {k: v for k, v in os.environ.items() if not k.startswith("OPENBLAS_")}
    if coretype is not None:
        env["OPENBLAS_CORETYPE"] = coretype
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    ).stdout
    assert json.loads(out.splitlines()[-1]) == [recorded["return"], recorded["length"]]

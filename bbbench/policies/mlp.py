"""A small MLP policy evaluated in plain numpy: the fast path of `bbbench eval`.

Its arithmetic is `bbbench.portable`'s: each layer's output the float32 nearest
the exact value, the same bits on every CPU, so an episode replays byte for byte
wherever the leaderboard is checked (torch's kernels, like numpy's `@`, round by
CPU). A greedy argmax policy (PPO, A2C, DQN acting deterministically) takes a
shortcut to the same actions: a float64 pass with a bound on its distance to that
network decides every step where the best output wins by more than the bound
(`MlpActor.estimate`; the rare closer call goes the long way). Its actions match
torch's to within 1e-6 (tests/test_policies.py); benchmarks/bench_eval.py times both
(docs/performance.md).
`MlpActor` holds only numpy arrays: it pickles into worker processes and Ray
tasks without torch.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from bbbench import portable


def _relu(x: np.ndarray) -> np.ndarray:
    return np.maximum(x, 0.0, out=x)


def _leaky_relu(x: np.ndarray) -> np.ndarray:  # torch's default slope, 0.01
    return np.where(x >= 0.0, x, x * np.float32(0.01))


def _elu(x: np.ndarray) -> np.ndarray:  # alpha = 1
    return np.where(x > 0.0, x, portable.expm1(x))


def _silu(x: np.ndarray) -> np.ndarray:
    return x * portable.sigmoid(x)


# torch.nn activation class names -> the same function in numpy (float32 in, float32 out).
ACTIVATIONS = {
    "Tanh": portable.tanh,
    "ReLU": _relu,
    "LeakyReLU": _leaky_relu,
    "ELU": _elu,
    "Sigmoid": portable.sigmoid,
    "SiLU": _silu,
}

# The activations `MlpActor.estimate` can bound the float64 pass through.
BOUNDED_ACTIVATIONS = ("Tanh", "ReLU")

# How the last layer's output becomes an action.
OUTPUTS = ("argmax", "gaussian", "squashed_gaussian", "tanh", "clip")
# SAC's clamp of its log standard deviation (stable_baselines3.sac.policies).
_LOG_STD_MIN, _LOG_STD_MAX = -20.0, 2.0


@dataclasses.dataclass(frozen=True, eq=False)
class MlpActor:
    """The acting part of a stable-baselines3 MLP policy, as numpy arrays.

    Args:
        hidden: (weight^T, bias) of each hidden layer, float32; each followed by `activation`.
        activation: a key of `ACTIVATIONS`.
        head: (weight^T, bias) of the output layer.
        output: "argmax" (logits or Q-values: PPO, A2C, DQN), "gaussian" (PPO and
            A2C on a Box: the mean, clipped to the bounds), "squashed_gaussian" (SAC:
            tanh of the mean, scaled to the bounds), "tanh" (TD3, and ARS or PPO with
            squash_output: tanh, scaled), "clip" (ARS: the output clipped to the bounds).
            Only "argmax", "gaussian" and "squashed_gaussian" sample when acting
            stochastically; the others act deterministically, as their `predict` does.
        log_std: PPO/A2C on a Box: the state-independent log standard deviation;
            SAC: (weight^T, bias) of its log-std layer; else None.
        epsilon: DQN's and QR-DQN's exploration rate: acting stochastically, they act
            epsilon-greedily (as their `predict` does) rather than sampling the logits.
        low, high: the Box action bounds (None for Discrete).
        quantiles: QR-DQN: the head gives `quantiles` values per action, and the action
            is the argmax of their mean.
        mean_clip: SAC and TQC with gSDE: the head's output is clipped to
            [-mean_clip, mean_clip] (their Hardtanh) before tanh.

    It acts on batches: the bots of a multi-bot task, or the lockstep episodes a
    worker plays together.
    """

    hidden: tuple[tuple[np.ndarray, np.ndarray], ...]
    activation: str
    head: tuple[np.ndarray, np.ndarray]
    output: str
    log_std: np.ndarray | tuple[np.ndarray, np.ndarray] | None = None
    epsilon: float | None = None
    low: np.ndarray | None = None
    high: np.ndarray | None = None
    quantiles: int = 1
    mean_clip: float | None = None

    def __post_init__(self) -> None:
        if self.activation not in ACTIVATIONS:
            raise ValueError(f"activation must be one of {sorted(ACTIVATIONS)}")
        if self.output not in OUTPUTS:
            raise ValueError(f"output must be one of {OUTPUTS}, got {self.output!r}")
        # The layers as `bbbench.portable` computes them: the same bits on every CPU.
        object.__setattr__(self, "_layers", tuple(portable.Layer(*layer) for layer in self.hidden))
        object.__setattr__(self, "_head", portable.Layer(*self.head))
        if self.output == "squashed_gaussian" and self.log_std is not None:
            object.__setattr__(self, "_log_std_layer", portable.Layer(*self.log_std))
        # Greedy argmax actions can come from float64 estimates with a bound on their
        # error (`greedy`): with tanh or ReLU, one output per action.
        greedy = self.output == "argmax" and self.quantiles == 1 and self.mean_clip is None
        estimable = greedy and self.activation in BOUNDED_ACTIVATIONS
        object.__setattr__(self, "_estimable", estimable)

    def latent(self, observation: np.ndarray) -> np.ndarray:
        """The last hidden layer's output."""
        activate = ACTIVATIONS[self.activation]
        x = np.asarray(observation, dtype=np.float32)
        for layer in self._layers:
            x = activate(layer(x))
        return x

    def __call__(
        self, observations: np.ndarray, rngs: Sequence[np.random.Generator] | None = None
    ) -> list:
        """Actions for a batch of observations, shape (k, n): a list of k actions, with
        None where the network's output is NaN. Deterministic, or sampled when `rngs`
        (one generator per row) is given."""
        if rngs is None and self._estimable:
            actions = self.greedy(observations)
            if actions is not None:
                return actions
        latent = self.latent(observations)
        out = self._head(latent)
        if self.quantiles > 1:  # (k, quantiles x actions) -> the mean over quantiles
            out = out.reshape(len(out), self.quantiles, -1).mean(axis=1)
        if self.mean_clip is not None:
            out = np.clip(out, -self.mean_clip, self.mean_clip)
        if self.output == "argmax":
            actions = out.argmax(axis=1).tolist()
            if rngs is not None:
                actions = [
                    self._sample(row, best, rng)
                    for row, best, rng in zip(out, actions, rngs, strict=True)
                ]
        else:
            if rngs is not None and self.output in ("gaussian", "squashed_gaussian"):
                noise = np.stack([rng.standard_normal(out.shape[1:], np.float32) for rng in rngs])
                if self.output == "gaussian":  # as stable-baselines3 does
                    log_std = self.log_std
                else:
                    log_std = np.clip(self._log_std_layer(latent), _LOG_STD_MIN, _LOG_STD_MAX)
                out = out + portable.exp32(log_std) * noise
            if self.output in ("gaussian", "clip"):
                action = np.clip(out, self.low, self.high)
            else:
                action = self.low + np.float32(0.5) * (portable.tanh(out) + np.float32(1.0)) * (
                    self.high - self.low
                )
            actions = list(action)
        total = out.sum()  # NaN if any output is (one numpy call on the hot path)
        if total != total:
            broken = np.isnan(out).any(axis=1)
            actions = [None if nan else action for action, nan in zip(actions, broken, strict=True)]
        return actions

    def outputs(self, observations: np.ndarray) -> np.ndarray:
        """The head's outputs, float32, as the network defines them (every layer's output
        the float32 nearest its exact value): what `__call__` acts on."""
        return self._head(self.latent(observations))

    def greedy(self, observations: np.ndarray) -> list[int] | None:
        """The argmax actions of the network `__call__` defines, from `estimate`: each
        row's argmax, when in every row the largest output beats the next by more than
        twice the bound. None when a row is that close (or NaN): the defined network
        then decides every row.

        The same actions at 0.4 of the cost (15.2 µs a call at batch 1, against 38.6 for
        the defined network: docs/performance.md).
        """
        out, error = self.estimate(observations)
        if out.shape[1] > 1:
            ordered = np.sort(out, axis=1)  # NaN last: its gap is NaN, which fails
            if not (ordered[:, -1] - ordered[:, -2]).min() > 2.0 * error:
                return None
        return out.argmax(axis=1).tolist()

    def estimate(self, observations: np.ndarray) -> tuple[np.ndarray, float]:
        """The head's outputs from a float64 pass with no rounding to float32, and a bound
        on how far each can be from the head's output as the network is defined (every
        layer's output the float32 nearest its exact value): `portable.Layer.error`
        through the layers. Tanh and ReLU networks only."""
        if self.activation not in BOUNDED_ACTIVATIONS:
            raise ValueError(f"no error bound for {self.activation} layers")
        x = np.asarray(observations, dtype=np.float64)
        size, error = float(np.abs(x).max(initial=0.0)), 0.0  # the input is exact
        tanh = self.activation == "Tanh"
        for layer in self._layers:
            y = layer.float64(x)
            # The bound from the outputs' actual size: for the first layer (the widest
            # inputs) and every ReLU layer (unbounded); tanh's inputs are within 1.
            top = float(np.abs(y).max(initial=0.0)) if not (tanh and error) else None
            error = layer.error(size, error, top)
            if tanh:  # tanh moves no value by more than its argument moved
                x, size, error = np.tanh(y), 1.0, portable.tanh_error(error)
            else:  # ReLU: max(y, 0) is no farther from max(Y, 0) than y from Y
                x, size = np.maximum(y, 0.0, out=y), top
        return self._head.float64(x), self._head.error(size, error)

    def _sample(self, out: np.ndarray, best: int, rng: np.random.Generator) -> int:
        n = out.shape[-1]
        if self.epsilon is not None:  # DQN, QR-DQN: epsilon-greedy
            return int(rng.integers(n)) if rng.random() < self.epsilon else best
        probabilities = portable.exp32(out - out[best])
        cumulative = np.cumsum(probabilities / probabilities.sum())
        return min(int(np.searchsorted(cumulative, rng.random(), side="right")), n - 1)

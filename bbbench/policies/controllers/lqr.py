"""The LQR baseline: a linear-quadratic regulator designed from a linear model of the bot
identified from the simulator.

**The model.** State s = (pitch [rad], pitch_rate [rad/s], wheel_speed [rad/s],
wheel_command [rad/s]), the first four observations; input u = the change of
wheel command this step [rad/s] (the action). Around upright, one control step
(0.01 s) is linear, s' = A s + B u. `identify()` fits A and B by least squares to
the simulator's own steps: FlatBalance-v0 episodes on training seeds, driven by the
PD baseline with Gaussian noise on its command changes (std 0.3 rad/s) so every
direction is excited, keeping the steps where |pitch| < 0.2 rad. The fit, with
`MODEL_A` and `MODEL_B` (rounded to 4 decimals):

    A = [[ 1.0019   0.0100   0.0031  -0.0031]     B = [-0.0031]
         [ 0.1919   0.9996   0.3100  -0.3101]         [-0.3121]
         [-0.0259  -0.0001   0.0087   0.9913]         [ 0.9920]
         [ 0        0        0        1     ]]        [ 1     ]

The wheels reach their command within a step (row 3), and leaning forward
accelerates the lean (A[1, 0] > 0): an inverted pendulum whose pivot the wheels move.
(the last row is the command's own integrator, exact). `python -m
bbbench.policies.controllers.lqr` identifies them again and prints them;
tests/test_baselines.py checks the stored ones still fit the simulator.

**The cost.** sum over steps of (s - s_ref)^T Q (s - s_ref) + R u^2 with
Q = diag(100, 1, 0.1, 0.01) and R = 1: pitch errors cost most; wheel speed is
weighted lightly, enough to hold the target velocity. The reference state for a
target velocity v is s_ref = (0, 0, v / r, v / r) with r the wheel radius: upright,
wheels turning at the target speed, an equilibrium of the model (a steady speed needs
no lean on flat ground), so tracking has no bias.

**The gains** K solve the discrete Riccati equation (iterated to convergence):
u = -K (s - s_ref), with K = `GAINS` = (-11.66, -2.124, -0.6632, 0.4169); the
closed loop A - B K is stable (tested). In continuous mode the change is
clipped to the action bounds; in discrete mode it is the nearest of the nine
changes of the action table. It reads only the shared observation layout, so it
plays every task.
"""

from __future__ import annotations

import numpy as np

from bbbench.envs.factory import make
from bbbench.policies.controllers.pd import PDController
from bbbench.robots.layout import INDEX
from bbbench.robots.twowheel import (
    ACTION_MODES,
    MAX_WHEEL_SPEED_CHANGE,
    TWO_WHEEL,
    WHEEL_SPEED_CHANGES,
)

STATE = ("pitch", "pitch_rate", "wheel_speed", "wheel_command")
COST_STATE = np.diag([100.0, 1.0, 0.1, 0.01])
COST_INPUT = 1.0
# The identified model (python -m bbbench.policies.controllers.lqr prints a fresh fit).
MODEL_A = np.array(
    [
        [1.0019, 0.0100, 0.0031, -0.0031],
        [0.1919, 0.9996, 0.3100, -0.3101],
        [-0.0259, -0.0001, 0.0087, 0.9913],
        [0.0, 0.0, 0.0, 1.0],
    ]
)
MODEL_B = np.array([-0.0031, -0.3121, 0.9920, 1.0])
_CHANGES = np.asarray(WHEEL_SPEED_CHANGES)
_STATE_INDEX = [INDEX[name] for name in STATE]


def lqr_gains(a: np.ndarray, b: np.ndarray, q: np.ndarray, r: float) -> np.ndarray:
    """K of the infinite-horizon discrete LQR, u = -K s: the Riccati equation iterated
    from P = Q until it stops changing."""
    b = b.reshape(-1, 1)
    p = q.copy()
    for _ in range(100_000):
        gain = np.linalg.solve(r + b.T @ p @ b, b.T @ p @ a)
        following = q + a.T @ p @ (a - b @ gain)
        if np.allclose(following, p, rtol=1e-12, atol=1e-12):
            break
        p = following
    else:
        raise ArithmeticError("the Riccati iteration did not converge: is (A, B) stabilizable?")
    return gain.ravel()


# lqr_gains(MODEL_A, MODEL_B, COST_STATE, COST_INPUT), written out: BLAS and LAPACK round
# differently on different CPUs, and the regulator must act the same on every machine
# (tests/test_baselines.py checks that the iteration still gives these).
GAINS = np.array(
    [-11.655270756516067, -2.1241769606962126, -0.6632380069273113, 0.41685225973135015]
)


class LQRController:
    """u = -K (s - s_ref) on each observation, in the env's action mode.

    Args:
        action_mode: "discrete" or "continuous".
        gains: K (default: `GAINS`, from the identified model and the cost above).
    """

    def __init__(self, action_mode: str = "discrete", gains: np.ndarray | None = None) -> None:
        if action_mode not in ACTION_MODES:
            raise ValueError(f"action_mode must be one of {ACTION_MODES}, got {action_mode!r}")
        self.action_mode = action_mode
        self.gains = GAINS if gains is None else np.asarray(gains, dtype=float)
        self._gains = tuple(self.gains.tolist())

    def wheel_speed_change(self, observation: np.ndarray) -> float:
        """The change of wheel command (rad/s) the regulator wants."""
        wheel_target = float(observation[INDEX["target_velocity"]]) / TWO_WHEEL.wheel_radius
        state = np.asarray(observation, dtype=float)[_STATE_INDEX]
        error = state - (0.0, 0.0, wheel_target, wheel_target)
        g0, g1, g2, g3 = self._gains  # summed in this order on every CPU (no BLAS)
        e0, e1, e2, e3 = error.tolist()
        return -(g0 * e0 + g1 * e1 + g2 * e2 + g3 * e3)

    def __call__(self, observation: np.ndarray) -> int | np.ndarray:
        """The action for one observation."""
        change = self.wheel_speed_change(observation)
        if self.action_mode == "discrete":
            return int(np.argmin(np.abs(_CHANGES - change)))
        return np.array([np.clip(change / MAX_WHEEL_SPEED_CHANGE, -1.0, 1.0)], dtype=np.float32)


def identify(
    episodes: int = 20, noise: float = 0.3, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """A and B fitted by least squares to FlatBalance-v0's steps (see the module docstring)."""
    env = make("bbbench/FlatBalance-v0", action_mode="continuous").unwrapped
    pd = PDController(action_mode="continuous")
    rng = np.random.default_rng(seed)
    rows, following = [], []
    for episode in range(episodes):
        observation, _ = env.reset(seed=episode)
        for _ in range(1500):
            change = pd.wheel_speed_change(observation) + rng.normal(0.0, noise)
            action = np.clip(change / MAX_WHEEL_SPEED_CHANGE, -1.0, 1.0)
            applied = float(action) * MAX_WHEEL_SPEED_CHANGE
            after, _, terminated, _, _ = env.step(np.array([action], dtype=np.float32))
            state = observation[_STATE_INDEX].astype(float)
            if abs(state[0]) < 0.2:
                rows.append([*state, applied])
                following.append(after[_STATE_INDEX].astype(float))
            observation = after
            if terminated:
                break
    env.close()
    fit, *_ = np.linalg.lstsq(np.array(rows), np.array(following), rcond=None)
    return fit[:4].T, fit[4]


def main() -> None:
    a, b = identify()
    np.set_printoptions(precision=4, suppress=True)
    print(f"A =\n{a}\nB = {b}\nK = {lqr_gains(a, b, COST_STATE, COST_INPUT)}")


if __name__ == "__main__":
    main()

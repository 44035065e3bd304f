"""One pybullet world per environment, and its lifecycle.

A `World` owns one `BulletClient`. It connects on first use (so constructing an
environment is cheap and `gym.make` never opens a window by accident), never
touches pybullet's global default connection, and pickles *without* its client:
a copy made by cloudpickle or `copy.deepcopy` reconnects to a world of its own
the next time it is used, so two copies never share bodies.
"""

from __future__ import annotations

import contextlib
import functools
import os
import sys

import numpy as np

from bbbench.quiet import c_output_silenced

with c_output_silenced():  # pybullet prints its build time when imported
    import pybullet
    from pybullet_utils.bullet_client import BulletClient

GRAVITY = 9.81  # m/s^2


class _Client(BulletClient):
    """A `BulletClient` that can be collected after an interrupted connect. pybullet_utils'
    `__del__` reads `_client`, which `__init__` sets only once `pybullet.connect` returns:
    a Ctrl-C during the connect left an object whose collection printed a traceback
    ("no attribute '_client'") beside the command's one line. -1 is "not connected"."""

    _client = -1


SOLVER_ITERATIONS = 10


def physics_parameters() -> dict[str, int]:
    """The engine settings every bbbench world uses besides gravity and its time step.

    A function, so a test can patch `SOLVER_ITERATIONS` and see the change.
    (docs/performance.md measures each.)
    """
    return {
        # Identical results for identical calls, whatever the order pairs were found in.
        "deterministicOverlappingPairs": 1,
        # pybullet's default is 50. Contacts are what the solver iterates over, and
        # terrain makes more of them: at 50, a bot on a heightfield stepped at 0.63x
        # its rate on a plane; at 10, 0.77-0.83x.
        "numSolverIterations": SOLVER_ITERATIONS,
        # Friction as two independent directions (the pyramid approximation of
        # PhysX and Unity) rather than bullet's default cone: +4% on flat ground,
        # +15% driving across terrain.
        "enableConeFriction": 0,
    }


def bullet_client_id(client: BulletClient) -> int:
    """The `physicsClientId` of a `BulletClient`, for hot paths that call pybullet's module
    functions directly (a client's methods build a partial per call). BulletClient keeps
    it in `_client` and has no public name for it: this is the one place that reads it."""
    return client._client


def check_display() -> None:
    """`RuntimeError` unless pybullet's GUI can open a window here. Without a display,
    pybullet's GUI connection ends the whole Python process (it calls `exit()`)."""
    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
        raise RuntimeError(
            'render_mode="human" opens pybullet\'s GUI window, which needs a display, and '
            "DISPLAY is not set: run under a desktop or `xvfb-run`, or use "
            'render_mode="rgb_array" (headless frames)'
        )


class World:
    """A pybullet physics world, created lazily and never shared.

    Args:
        time_step: simulated seconds advanced by one `step()`.
        substeps: physics sub-steps per `step()` (pybullet's `numSubSteps`);
            each lasts `time_step / substeps`. One `stepSimulation` call either way.
        gui: open pybullet's GUI instead of a headless (DIRECT) server.
    """

    _gui_world_open = False  # pybullet allows one GUI connection per process

    def __init__(self, time_step: float, substeps: int = 1, gui: bool = False) -> None:
        if not time_step > 0:
            raise ValueError(f"time_step must be positive seconds, got {time_step!r}")
        if int(substeps) != substeps or substeps < 1:
            raise ValueError(f"substeps must be a whole number >= 1, got {substeps!r}")
        self.time_step = float(time_step)
        self.substeps = int(substeps)
        self.gui = bool(gui)
        self._client: BulletClient | None = None
        self._client_id = -1  # the connected client's id, for `step()`

    @property
    def connected(self) -> bool:
        return self._client is not None

    @property
    def client(self) -> BulletClient:
        """The world's client, connecting (and configuring) it on first use."""
        if self._client is None:
            self._client = self._connect()
            self._client_id = bullet_client_id(self._client)
            self.step = functools.partial(pybullet.stepSimulation, self._client_id)
        return self._client

    @property
    def client_id(self) -> int:
        """The pybullet `physicsClientId`, for hot paths that call pybullet directly."""
        return bullet_client_id(self.client)

    def step(self) -> None:
        """Advance the world by `time_step` (one `stepSimulation`, of `substeps` sub-steps).

        Once connected, `world.step` is `pybullet.stepSimulation` bound to the world's
        client (a partial: no Python frame on the hot path); before, it connects first.
        """
        self.client  # noqa: B018 (connects, and binds `step`)
        self.step()

    def detect_collisions(self) -> None:
        """Run collision detection alone, without stepping: contact points refreshed."""
        pybullet.performCollisionDetection(self.client_id)

    def _connect(self) -> BulletClient:
        if not self.gui:
            with c_output_silenced():  # and "argv[0]=" when it connects
                client = _Client(connection_mode=pybullet.DIRECT)
        else:
            check_display()
            # pybullet allows one GUI per process; ask before it fails half-way.
            if World._gui_world_open:
                raise RuntimeError(
                    'render_mode="human" opens pybullet\'s GUI, and pybullet allows one GUI '
                    "per process: close() the other human-rendering env first, or use "
                    'render_mode="rgb_array"'
                )
            client = _Client(connection_mode=pybullet.GUI)
            World._gui_world_open = True
            # The side panels cost frames and hide the robot; the follow camera does the rest.
            client.configureDebugVisualizer(pybullet.COV_ENABLE_GUI, 0)
        self._configure(client)
        return client

    def _configure(self, client: BulletClient) -> None:
        client.setGravity(0.0, 0.0, -GRAVITY)
        client.setPhysicsEngineParameter(
            fixedTimeStep=self.time_step,  # the whole step: pybullet divides it by numSubSteps
            numSubSteps=self.substeps,
            **physics_parameters(),
        )

    def camera_image(
        self,
        target: tuple[float, float, float],
        distance: float,
        yaw: float,
        pitch: float,
        size: tuple[int, int],
    ) -> np.ndarray:
        """An RGB frame (height, width, 3) of uint8 from pybullet's TinyRenderer (headless).

        The camera looks at `target` from `distance` m, turned by `yaw` and
        `pitch` degrees (pybullet's debug-camera convention); `size` is (width, height).
        """
        client = self.client
        width, height = size
        view = client.computeViewMatrixFromYawPitchRoll(
            cameraTargetPosition=target,
            distance=distance,
            yaw=yaw,
            pitch=pitch,
            roll=0.0,
            upAxisIndex=2,
        )
        projection = client.computeProjectionMatrixFOV(
            fov=50.0, aspect=width / height, nearVal=0.05, farVal=100.0
        )
        _, _, rgba, _, _ = client.getCameraImage(
            width,
            height,
            viewMatrix=view,
            projectionMatrix=projection,
            renderer=pybullet.ER_TINY_RENDERER,
        )
        frame = np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)
        return np.ascontiguousarray(frame[:, :, :3])

    def clear(self) -> None:
        """Empty the world as a fresh one (no bodies, the same settings), keeping the
        connection: `resetSimulation` and the settings again, without connecting anew
        (a connection costs about 27 ms; docs/performance.md)."""
        if self._client is None:
            return
        self._client.resetSimulation()
        self._configure(self._client)

    def close(self) -> None:
        """Disconnect; the next use of `client` connects a fresh world."""
        if self._client is not None:
            # The server may already be gone (a GUI window closed by hand).
            with contextlib.suppress(pybullet.error):
                self._client.disconnect()
            self._client = None
            self._client_id = -1
            self.__dict__.pop("step", None)
            if self.gui:
                World._gui_world_open = False

    def __getstate__(self) -> dict:
        # A pickled world is a description, never a connection: the copy builds its own.
        state = self.__dict__.copy()
        state["_client"] = None
        state["_client_id"] = -1
        state.pop("step", None)
        return state

    def __del__(self) -> None:
        self.close()

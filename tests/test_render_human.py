"""render_mode="human": pybullet's GUI, opened only when asked for. Needs a display
(.ci/run runs this file under xvfb-run)."""

from __future__ import annotations

import os
import time

import gymnasium as gym
import pybullet
import pytest

from conftest import FLAT

pytestmark = pytest.mark.skipif(
    not os.environ.get("DISPLAY"), reason="needs a display: run under xvfb-run, as .ci/run does"
)


def test_human_mode_opens_one_gui_that_follows_the_bot():
    env = gym.make(FLAT, render_mode="human")
    assert not env.unwrapped.scene.world.connected  # nothing opens before reset
    env.reset(seed=0)
    client_id = env.unwrapped.scene.world.client_id
    assert pybullet.getConnectionInfo(client_id)["connectionMethod"] == pybullet.GUI
    env.unwrapped.scene.bots[0].reset(xy=(1.5, -2.0))  # far from where the camera started
    for _ in range(5):
        env.step(4)
    x, y, _ = env.unwrapped.scene.bots[0].read().position
    # The GUI thread applies camera moves asynchronously: allow it a moment.
    deadline = time.monotonic() + 2.0
    while time.monotonic() < deadline:
        camera_target = pybullet.getDebugVisualizerCamera(client_id)[11]
        if camera_target[:2] == pytest.approx((x, y), abs=0.01):
            break
        time.sleep(0.05)
    assert camera_target[:2] == pytest.approx((x, y), abs=0.01)
    assert env.render() is None

    second = gym.make(FLAT, render_mode="human")
    with pytest.raises(RuntimeError, match="one GUI per process"):
        second.reset(seed=0)
    env.close()
    second.reset(seed=0)  # the GUI is free again
    second.close()

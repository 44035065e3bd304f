"""Shared helpers: the tests read as examples of using bbbench."""

from __future__ import annotations

import base64
import json
import os
import pickle
import shutil
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import bbbench
from bbbench.cli import main
from bbbench.policies import load_policy
from bbbench.policies.policy import act_once

FLAT = "bbbench/FlatBalance-v0"
# Each task whose latest version plays the reward in which staying up never costs, and the
# version before it: the same episodes under the first reward.
REWARD_SUCCESSORS = {
    "bbbench/FlatBalance-v1": "bbbench/FlatBalance-v0",
    "bbbench/VelocityTracking-v1": "bbbench/VelocityTracking-v0",
    "bbbench/NoisySensors-v1": "bbbench/NoisySensors-v0",
    "bbbench/Bumps-v2": "bbbench/Bumps-v1",
    "bbbench/Obstacles-v2": "bbbench/Obstacles-v1",
    "bbbench/Slopes-v2": "bbbench/Slopes-v1",
    "bbbench/MultiBalance-v1": "bbbench/MultiBalance-v0",
    "bbbench/MultiBumps-v1": "bbbench/MultiBumps-v0",
}


DOCS = Path(__file__).resolve().parents[1] / "docs"
RESULTS_SCHEMA = json.loads((DOCS / "results-schema.json").read_text())


def follows_results_schema(document: dict) -> None:
    """Raise unless `document` (a results document as `json.loads` reads it back) follows
    docs/results-schema.json, the schema every kind of policy's record is published in.
    (jsonschema is a test extra: the newer-Python step of .ci/run installs bbbench and
    pytest alone, and loads this module.)"""
    import jsonschema  # lazy: jsonschema, not in the newer-Python step's environment

    jsonschema.validate(document, RESULTS_SCHEMA)


def rollout(env: gym.Env, seed: int, actions) -> tuple[np.ndarray, np.ndarray]:
    """Observations (reset's first) and rewards of `actions` from `reset(seed=seed)`."""
    observation, _ = env.reset(seed=seed)
    observations, rewards = [observation], []
    for action in actions:
        observation, reward, terminated, truncated, _ = env.step(action)
        observations.append(observation)
        rewards.append(reward)
        if terminated or truncated:
            observation, _ = env.reset()
            observations.append(observation)
    return np.array(observations), np.array(rewards)


def fixed_actions(n: int, action_mode: str = "discrete", seed: int = 7) -> list:
    rng = np.random.default_rng(seed)
    if action_mode == "discrete":
        return [int(a) for a in rng.integers(0, 9, size=n)]
    return [np.array([a], dtype=np.float32) for a in rng.uniform(-1, 1, size=n)]


# The fixtures whose tests are slow (`pytest -m slow`): they build or check a leaderboard
# (playing its episodes), or drive a browser. Trainings, BenchMARL and Ray carry the
# marker themselves.
SLOW_FIXTURES = {"built", "board", "command_board", "chromium"}


def pytest_collection_modifyitems(items) -> None:
    for item in items:
        if SLOW_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="session")
def chromium():
    """A headless Chromium driven by Selenium. Skipped where Chromium is not installed,
    unless BBBENCH_REQUIRE_BROWSER is set (as .ci/run sets it): then it fails."""
    browser, driver = shutil.which("chromium"), shutil.which("chromedriver")
    if not (browser and driver):
        if os.environ.get("BBBENCH_REQUIRE_BROWSER"):
            pytest.fail("Chromium and chromedriver are required (apt-get install chromium ...)")
        pytest.skip("needs chromium and chromium-driver (Debian packages)")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = browser
    for argument in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1400,1000"):
        options.add_argument(argument)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    session = webdriver.Chrome(service=Service(executable_path=driver), options=options)
    yield session
    session.quit()


@pytest.fixture(params=["discrete", "continuous"])
def action_mode(request) -> str:
    return request.param


@pytest.fixture
def flat_env(action_mode):
    env = bbbench.make(FLAT, action_mode=action_mode)
    yield env
    env.close()


# -- policy files, honest and hostile -----------------------------------------------


@pytest.fixture
def marker(tmp_path) -> Path:
    """A file a pickle payload would create: its absence shows no code ran."""
    return tmp_path / "payload-ran"


class Payload:
    """Unpickling this creates `path` (a stand-in for any code an attacker runs)."""

    def __init__(self, path: Path) -> None:
        self.path = str(path)

    def __reduce__(self):
        return (open, (self.path, "w"))


def rewrite(source: Path, target: Path, change_data=None, members: dict | None = None) -> Path:
    """A copy of a zip with its `data` JSON changed and members added or replaced."""
    members = dict(members or {})
    with zipfile.ZipFile(source) as archive:
        for info in archive.infolist():
            members.setdefault(info.filename, archive.read(info.filename))
    if change_data is not None:
        data = json.loads(members["data"])
        change_data(data)
        members["data"] = json.dumps(data).encode()
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, content in members.items():
            archive.writestr(name, content)
    return target


def pickled(marker: Path) -> dict:
    return {
        ":type:": "<class 'abc.ABCMeta'>",
        ":serialized:": base64.b64encode(pickle.dumps(Payload(marker))).decode(),
    }


def one_line_exit_2(capsys, *argv: str) -> str:
    """`bbbench ARGV`'s error: exit code 2 and one line (what it printed to stderr)."""
    code = main(list(argv))
    err = capsys.readouterr().err
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1, err
    return err


def eval_exit(capsys, *argv: str) -> tuple[int, str]:
    code = main(["eval", *argv, "--episodes", "1", "--workers", "1"])
    return code, capsys.readouterr().err


def assert_acts_as_predict(path: Path, model, steps: int = 200, **load) -> None:
    """bbbench's numpy actor and its torch actor give `model.predict`'s deterministic actions
    on VelocityTracking-v0, whose target changes (so every observation input matters)."""
    task = "bbbench/VelocityTracking-v0"
    policy = load_policy(path, **load)
    numpy_actor = policy.actor(task)
    torch_actor = load_policy(path, backend="torch", **load).actor(task)
    env = bbbench.make(task, action_mode=policy.action_mode)
    observation, _ = env.reset(seed=3)
    for _ in range(steps):
        expected, _ = model.predict(observation, deterministic=True)
        ours, theirs = act_once(numpy_actor, observation), act_once(torch_actor, observation)
        if policy.action_mode == "discrete":
            assert ours == theirs == int(expected)
        else:
            np.testing.assert_array_equal(theirs, expected)
            np.testing.assert_allclose(ours, expected, rtol=0, atol=1e-6)
        observation, _, terminated, truncated, _ = env.step(expected)
        if terminated or truncated:
            observation, _ = env.reset()


def load_script(name: str):
    """`scripts/<name>.py` as a module (registered under its name: a dataclass there
    looks its module up), with scripts/ on `sys.path` as when Python runs it, so that it
    imports its neighbours as it does there."""
    import importlib.util
    import sys

    scripts = Path(__file__).resolve().parents[1] / "scripts"
    if str(scripts) not in sys.path:
        sys.path.append(str(scripts))
    found = importlib.util.spec_from_file_location(name, scripts / f"{name}.py")
    module = importlib.util.module_from_spec(found)
    sys.modules[name] = module
    found.loader.exec_module(module)
    return module

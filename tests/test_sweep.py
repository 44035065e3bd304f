"""`bbbench sweep`: the harness's episodes at each value of an axis, the same bytes every
run and with any number of workers, and a one-line error for every mistake."""

from __future__ import annotations

import json

import jsonschema
import numpy as np
import pytest

import bbbench
from bbbench.cli import main
from bbbench.evaluation import evaluate
from bbbench.evaluation.sweep import AXES, standard_grid, sweep
from bbbench.policies import load_policy
from bbbench.tasks.perturbations import PERTURBATIONS
from conftest import DOCS, RESULTS_SCHEMA

VELOCITY = "bbbench/VelocityTracking-v1"
SCHEMA = json.loads((DOCS / "sweep-schema.json").read_text())


def test_the_same_sweep_writes_the_same_bytes_twice_and_with_one_or_two_workers(tmp_path):
    runs = []
    for name, workers in (("a", 1), ("b", 2), ("c", 2)):
        out, plot = tmp_path / f"{name}.json", tmp_path / f"{name}.svg"
        argv = ["sweep", "pd", "--axis", "push", "--values", "0,0.5", "--episodes", "9"]
        argv += ["--workers", str(workers), "--json", str(out), "--plot", str(plot)]
        assert main(argv) == 0
        runs.append((out.read_bytes(), plot.read_bytes()))
    assert runs[0] == runs[1] == runs[2]
    assert b"<svg" in runs[0][1]
    document = json.loads(runs[0][0])
    jsonschema.validate(document, SCHEMA)
    aggregate = RESULTS_SCHEMA["properties"]["tasks"]["items"]["properties"]["aggregate"]
    for point in document["policies"][0]["tasks"][0]["points"]:
        jsonschema.validate(point["aggregate"], aggregate)


def test_a_sweep_point_is_the_harness_result_of_that_task():
    """At a value that leaves the task as built, a point's aggregate is `evaluate`'s: the
    same episodes, through the same player."""
    policy = load_policy("pd")
    document = sweep([policy], "payload_mass", [0.0, 1.0], [VELOCITY], episodes=8, workers=1)
    plain = evaluate(policy, [VELOCITY], episodes=8, workers=1).document["tasks"][0]
    points = document["policies"][0]["tasks"][0]["points"]
    assert points[0]["aggregate"] == plain["aggregate"]
    assert points[0]["fingerprint"] == plain["fingerprint"]
    assert points[1]["fingerprint"] != plain["fingerprint"]
    assert points[1]["aggregate"] != plain["aggregate"]


def test_robustness_is_the_mean_and_worst_case_the_minimum_over_the_grid():
    document = sweep([load_policy("pd")], "sensor_noise", None, [VELOCITY], episodes=4)
    assert document["values"] == list(standard_grid("sensor_noise"))
    assert document["standard_grid"] is True
    task = document["policies"][0]["tasks"][0]
    scores = [point["aggregate"]["normalized_score"] for point in task["points"]]
    assert task["robustness"]["score"] == pytest.approx(np.mean(scores), abs=1e-12)
    assert task["robustness"]["worst_case"] == min(scores)
    assert task["robustness"]["worst_value"] == document["values"][int(np.argmin(scores))]
    assert scores[0] > scores[-1]  # PD loses score to noise


def test_difficulty_and_n_bots_are_axes_of_their_tasks(capsys):
    terrain = sweep([load_policy("pd")], "difficulty", [0.2, 0.9], ["bbbench/Bumps-v2"], 8)
    easy, hard = (p["aggregate"] for p in terrain["policies"][0]["tasks"][0]["points"])
    assert easy["normalized_score"] > hard["normalized_score"]
    bots = sweep([load_policy("pd")], "n_bots", [2, 3], ["bbbench/MultiBalance-v1"], 2)
    points = bots["policies"][0]["tasks"][0]["points"]
    assert [p["aggregate"]["episodes"] for p in points] == [2, 2]
    assert points[0]["fingerprint"] != points[1]["fingerprint"]


def test_several_policies_are_overlaid_in_one_document(tmp_path):
    out = tmp_path / "sweep.json"
    argv = ["sweep", "pd", "zero", "--axis", "friction", "--values", "0.5,1"]
    assert main([*argv, "--episodes", "2", "--json", str(out)]) == 0
    document = json.loads(out.read_text())
    assert [entry["policy"]["name"] for entry in document["policies"]] == ["pd", "zero"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--axis", "payload"], "unknown axis 'payload': did you mean 'payload_mass'?"),
        (["--axis", "payload_mass", "--values", "-1"], "payload_mass must be in [0, 10]"),
        (["--axis", "friction", "--values", "0,1"], "friction must be in (0, 10]"),
        (["--axis", "action_delay", "--values", "1.5"], "action_delay is a whole number"),
        (["--axis", "action_delay", "--values", "-2"], "action_delay must be in [0, 100]"),
        (["--axis", "push", "--values", "a,b"], "'a' is not a number"),
        (["--axis", "difficulty", "--task", "bbbench/FlatBalance-v1"], "difficulty does not"),
        (["--axis", "n_bots", "--task", VELOCITY], "n_bots does not apply to"),
        (
            ["--axis", "n_bots", "--values", "20", "--task", "bbbench/MultiBalance-v1"],
            "n_bots must be from 2 to 16",
        ),
        (
            ["--axis", "sensor_noise", "--task", "bbbench/MultiBalance-v1"],
            "sensor_noise does not apply to bbbench/MultiBalance-v1",
        ),
        (["--axis", "push", "--plot", "out.pdf"], "written as .svg or .png"),
        (["--axis", "push", "--episodes", "0"], "--episodes must be at least 1"),
    ],
)
def test_a_mistake_is_one_line_exit_2_and_nothing_written(argv, message, tmp_path, capsys):
    out = tmp_path / "sweep.json"
    assert main(["sweep", "pd", *argv, "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err
    assert err.count("\n") == 1
    assert "Traceback" not in err
    assert not out.exists()


def test_every_axis_has_a_standard_grid_its_component_accepts():
    assert set(AXES) == {*PERTURBATIONS, "difficulty", "n_bots"}
    task = bbbench.spec(VELOCITY)
    for keyword, kind in PERTURBATIONS.items():
        assert standard_grid(keyword) == kind.grid
        for value in kind.grid:
            task.with_perturbation(kind(value))

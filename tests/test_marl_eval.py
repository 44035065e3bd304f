"""`bbbench eval --marl-eval OUT`: the episodes in marl-eval's raw-data format, read by
marl-eval's own checks and processing (InstaDeep's id-marl-eval; .ci/run installs it
without its plotting dependencies, and sets BBBENCH_REQUIRE_MARL_EVAL=1)."""

from __future__ import annotations

import json
import os

import pytest

from bbbench.cli import main
from bbbench.evaluation.results import read

TASKS = ["bbbench/MultiBalance-v1", "bbbench/BeamCarry-v0"]


def marl_eval():
    try:
        from marl_eval.utils import data_processing_utils, diagnose_data_errors
    except ImportError:
        if os.environ.get("BBBENCH_REQUIRE_MARL_EVAL") == "1":
            raise
        pytest.skip("id-marl-eval is not installed (.ci/run installs it)")
    return data_processing_utils, diagnose_data_errors


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    folder = tmp_path_factory.mktemp("marl-eval")
    out, results = folder / "pd.json", folder / "results.json"
    argv = ["eval", "pd", "--task", *TASKS, "--episodes", "3", "--workers", "1"]
    assert main([*argv, "--marl-eval", str(out), "--json", str(results)]) == 0
    return json.loads(out.read_text()), read(results)


def test_the_file_holds_every_episode_of_every_task(written):
    data, results = written
    assert set(data) == {"bbbench"}
    assert set(data["bbbench"]) == {"MultiBalance-v1", "BeamCarry-v0"}
    for block in results["tasks"]:
        run = data["bbbench"][block["task"].removeprefix("bbbench/")]["pd"]["run_pd"]
        returns = [episode["return"] for episode in block["episodes"]]
        assert run["step_0"]["return"] == run["absolute_metrics"]["return"] == returns
        assert run["step_0"]["step_count"] == 0
        assert len(run["step_0"]["success"]) == len(returns) == 3


def test_marl_evals_own_reader_takes_it(written):
    processing, diagnose = marl_eval()
    data, _ = written
    assert diagnose.DiagnoseData(data).check_data()["bbbench"] == {
        "valid_algorithms": True,
        "valid_algorithm_names": True,
        "valid_runs": True,
        "valid_steps": True,
        "valid_metrics": True,
    }
    processed = processing.data_process_pipeline(data, ["return"])
    step = processed["bbbench"]["multibalance-v1"]["pd"]["run_pd"]["step_0"]
    assert step["mean_return"] == pytest.approx(sum(step["return"]) / 3)
    matrices = processing.create_matrices_for_rliable(processed, "bbbench", ["return"])
    assert matrices


def test_an_onnx_policy_records_its_training_steps_and_its_run(tmp_path):
    from bbbench.policies import export_zip, load_policy

    path = export_zip(load_policy("reference"), tmp_path / "p.onnx", training_steps=400_000)
    out = tmp_path / "m.json"
    argv = ["eval", str(path), "--task", "bbbench/FlatBalance-v1", "--episodes", "2"]
    assert main([*argv, "--workers", "1", "--marl-eval", str(out)]) == 0
    [(run, steps)] = json.loads(out.read_text())["bbbench"]["FlatBalance-v1"]["PPO"].items()
    assert run.startswith("run_")
    assert steps["step_0"]["step_count"] == 400_000


def test_runs_are_named_by_training_seed_so_two_algorithms_merge_in_marl_eval(tmp_path):
    """IPPO's and MAPPO's files of seeds 0 and 1, each evaluated alone, merge into one
    document that marl-eval's pipeline turns into rliable's matrices (it wants the same
    run names for every algorithm)."""
    import torch

    from bbbench.policies import onnx_bytes

    processing, _ = marl_eval()
    task = "bbbench/MultiBalance-v1"
    merged: dict = {}
    for algorithm in ("IPPO", "MAPPO"):
        for seed in (0, 1):
            torch.manual_seed(seed)
            network = torch.nn.Linear(17, 9)
            path = tmp_path / f"{algorithm}-{seed}.onnx"
            path.write_bytes(onnx_bytes(network, task, algorithm=algorithm, training_seed=seed))
            out = tmp_path / f"{algorithm}-{seed}.json"
            argv = ["eval", str(path), "--task", task, "--episodes", "2", "--workers", "1"]
            assert main([*argv, "--marl-eval", str(out)]) == 0
            runs = json.loads(out.read_text())["bbbench"]["MultiBalance-v1"][algorithm]
            assert list(runs) == [f"run_{seed}"]
            merged.setdefault(algorithm, {}).update(runs)
    data = {"bbbench": {"MultiBalance-v1": merged}}
    processed = processing.data_process_pipeline(data, ["return"])
    matrices = processing.create_matrices_for_rliable(processed, "bbbench", ["return"])
    assert matrices

"""scripts/marl_curves.py, which draws the MARL campaign's sample-efficiency curves from
the runs' curve.json files: the IQM over every seed's training episodes at each point,
its stratified-bootstrap interval, and marl-eval's raw data of the same curves."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bbbench.evaluation.results import normalized
from bbbench.tasks.suite import spec
from conftest import load_script

TASK = "bbbench/MultiBalance-v1"


def fake_runs(root: Path, stem: str, levels: dict[int, list[float]]) -> None:
    """Seed s's curve: at point i, 12 episodes returning levels[s][i] plus a spread."""
    for seed, means in levels.items():
        folder = root / f"{stem}-s{seed}"
        folder.mkdir(parents=True)
        points = [
            {"steps": 300_000 * (i + 1), "returns": list(mean + np.linspace(-6.0, 6.0, 12))}
            for i, mean in enumerate(means)
        ]
        (folder / "curve.json").write_text(json.dumps({"points": points}))


def test_the_curve_pools_every_seeds_episodes_at_each_point(tmp_path):
    curves = load_script("marl_curves")
    fake_runs(tmp_path, "ippo-multibalance-v1-3m", {0: [40.0, 80.0], 2: [60.0, 100.0]})
    runs = curves.cell_runs(tmp_path, "ippo-multibalance-v1-3m")
    assert sorted(runs) == [0, 2]  # seed 1 not trained yet: left out
    points = curves.curve(TASK, runs)
    assert [point["steps"] for point in points] == [300_000, 600_000]
    task = spec(TASK)
    pooled = [normalized(v, task) for seed in (0, 2) for v in runs[seed][1]["returns"]]
    assert points[1]["iqm"] == pytest.approx(float(np.mean(sorted(pooled)[6:18])))
    low, high = points[1]["ci"]
    assert low < points[1]["iqm"] < high
    assert points[0]["iqm"] < points[1]["iqm"]


def test_the_curves_go_through_marl_evals_own_pipeline(tmp_path):
    try:
        from marl_eval.utils import data_processing_utils
    except ImportError:
        pytest.skip("id-marl-eval is not installed (.ci/run installs it)")
    curves = load_script("marl_curves")
    data = {}
    for method, shift in (("ippo", 0.0), ("mappo", 10.0)):
        stem = f"{method}-multibalance-v1-3m"
        fake_runs(tmp_path, stem, {s: [40.0 + shift + s, 90.0 + shift] for s in (0, 1, 2)})
        runs = curves.cell_runs(tmp_path, stem)
        data[method.upper()] = curves.marl_eval_curves(runs, {})
    document = {"bbbench": {"MultiBalance-v1": data}}
    processed = data_processing_utils.data_process_pipeline(document, ["return"])
    matrices = data_processing_utils.create_matrices_for_rliable(processed, "bbbench", ["return"])
    assert matrices


def test_the_script_draws_each_task_with_its_controllers_line(tmp_path, monkeypatch, capsys):
    curves = load_script("marl_curves")
    fake_runs(tmp_path, "ippo-x", {0: [40.0, 80.0], 1: [50.0, 90.0]})
    out = tmp_path / "images"
    out.mkdir()
    argv = ["marl_curves.py", "--root", str(tmp_path), "--out", str(out)]
    argv += ["--cells", f"ippo=ippo-x {TASK}", "--marl-eval", str(tmp_path / "m.json")]
    monkeypatch.setattr("sys.argv", argv)
    curves.main()
    printed = capsys.readouterr().out
    assert "| IPPO | 600,000 |" in printed
    assert "pd on the same seeds" in printed
    svg = (out / "marl-curves-multibalance-v1.svg").read_text()
    assert svg.startswith("<?xml")
    assert "pd controller" in svg
    data = json.loads((tmp_path / "m.json").read_text())
    assert sorted(data["bbbench"]["MultiBalance-v1"]["IPPO"]) == ["run_0", "run_1"]


def test_a_curve_is_quoted_by_its_points_and_its_ends_interval_against_the_line():
    curves = load_script("marl_curves")
    steps = [300_000 * (i + 1) for i in range(10)]  # 0.3M to 3M
    points = [{"steps": s, "iqm": s / 1e7, "ci": (s / 1e7 - 0.05, s / 1e7 + 0.05)} for s in steps]
    quoted = curves.milestones(points)
    assert [p["steps"] for p in quoted] == [900_000, 2_100_000, 3_000_000]  # nearest 1M, 2M
    assert curves.milestones(points[:2]) == points[1:2]  # a curve shorter than 1M: its end
    end = points[-1]  # 0.3 [0.25, 0.35]
    assert curves.against_line(end, 0.2) == "above it"
    assert curves.against_line(end, 0.4) == "below it"
    assert curves.against_line(end, 0.3).startswith("level")


@pytest.mark.parametrize(
    ("cells", "said"),
    [
        (None, "--out {out}: no such directory"),
        ("ippo=ippo-x", "expected METHOD=STEM TASK"),
        ("ippo=ippo-x bbbench/Nope-v0", "unknown task 'bbbench/Nope-v0'"),
        (f"ippo=ippo-y {TASK}", "no run found; expected one of {root}/ippo-y-s0/curve.json"),
    ],
)
def test_bad_input_is_one_line_and_exit_2_with_nothing_written(
    tmp_path, monkeypatch, capsys, cells, said
):
    curves = load_script("marl_curves")
    fake_runs(tmp_path, "ippo-x", {0: [40.0, 80.0]})
    out = tmp_path / ("missing" if cells is None else "images")
    if cells is not None:
        out.mkdir()
    argv = ["marl_curves.py", "--root", str(tmp_path), "--out", str(out)]
    argv += ["--cells", cells or f"ippo=ippo-x {TASK}"]
    monkeypatch.setattr("sys.argv", argv)
    with pytest.raises(SystemExit) as stopped:
        curves.main()
    assert stopped.value.code == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert said.format(out=out, root=tmp_path) in error
    assert not out.exists() or not any(out.iterdir())

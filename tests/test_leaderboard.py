"""The leaderboard: built from submissions, byte for byte; checked; added to; refused."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import gymnasium as gym
import jsonschema
import numpy as np
import pytest
import referencing
from stable_baselines3 import PPO

import bbbench
from bbbench import leaderboard
from bbbench.cli import main
from bbbench.evaluation import dumps, evaluate, stats
from bbbench.evaluation.profile import Protocol
from bbbench.evaluation.results import read
from bbbench.evaluation.team_sizes import TeamSizes
from bbbench.leaderboard import Board, SubmissionError
from bbbench.leaderboard.board import is_profile
from bbbench.leaderboard.fields import METHOD_FIELDS, schema_files
from bbbench.leaderboard.ranking import leaderboard_document
from bbbench.leaderboard.submissions import read_method, read_methods
from bbbench.policies import export_zip, load_policy
from bbbench.policies.registry import REFERENCE_POLICY, TERRAIN_POLICIES
from bbbench.tasks.spec import TaskSpec
from conftest import pickled, rewrite

DOCS = Path(__file__).parent.parent / "docs"
# Small enough to build in seconds; an old and a new version of one task, both tracks.
BOARD = Board(
    tasks=(
        "bbbench/Bumps-v0",
        "bbbench/Bumps-v1",
        "bbbench/FlatBalance-v0",
        "bbbench/MultiBalance-v0",
        # PD and random differ on its first 4 seeds (on BeamCarry's, PD falls in 2 as
        # early as random does); the track's profile plays BeamCarry.
        "bbbench/Convoy-v0",
    ),
    episodes=4,
    # Two axes, two seeds: a profile in seconds (the board's: seven axes, 20 seeds).
    profile=Protocol(episodes=2, axes=("action_delay", "push")),
    # Two sizes, one seed (the board's: 2, 4, 6 and 8 bots, 20 seeds).
    team_sizes=TeamSizes(episodes=1, sizes=(2, 3)),
)
PROFILE = 2 * 5 * 2  # a profile's episodes on BOARD: 2 axes, 5 values each, 2 seeds
SIZES = 2 * 1  # a team-size profile's: 2 sizes, 1 seed
# Every episode of the test board: pd, random and the three runs of ppo play the three
# single-bot tasks, pd and random the multi-bot one and the team one; pd and random are
# profiled on the three tracks, each run of ppo on the single-bot one; pd and random play
# team sizes on the multi-bot track.
EPISODES = 5 * 3 * 4 + 2 * 4 + 2 * 4 + 9 * PROFILE + 2 * SIZES
GENERATED = ("bbbench-v0.json", "README.md", "index.html")
RECIPE = {"world_steps": 400_000, "tasks": ["bbbench/VelocityTracking-v0"], "file": "sb3 defaults"}
# Three PPO policies of the suite, as the three runs of one method (a fiction: they were
# trained on different tasks; what matters here is that they differ).
PPO_RUNS = {
    "s0": REFERENCE_POLICY,
    "s1": TERRAIN_POLICIES["ppo-bumps-v1"],
    "s2": TERRAIN_POLICIES["ppo-obstacles-v1"],
}


def submission(**changes) -> dict:
    """A controller's method: one run, in its own folder."""
    data = {
        "name": "PD baseline",
        "authors": ["A. Person"],
        "algorithm": "PD",
        "action_mode": "discrete",
        "builtin": "pd",
        "tracks": ["single", "multi", "cooperative"],
        "recipe": {"world_steps": 0, "tasks": [], "file": "none"},
        "training_seed": None,
        "command": "built in",
        "wall_time": "none",
        "hardware": "none",
        "licence": "MIT",
    }
    data.update(changes)
    return {
        key: value for key, value in data.items() if value is not None or key == "training_seed"
    }


def run_record(seed: int, **changes) -> dict:
    record = {
        "training_seed": seed,
        "recipe": RECIPE,
        "command": f"train.py --seed {seed}",
        "wall_time": "10 min",
        "hardware": "laptop",
    }
    return {**record, **changes}


def write_submission(root: Path, slug: str, data: dict, policy: Path | None = None) -> Path:
    folder = root / "submissions" / slug
    folder.mkdir(parents=True)
    (folder / "submission.json").write_text(json.dumps(data))
    if policy is not None:
        shutil.copyfile(policy, folder / "policy.zip")
    return folder


def write_run(root: Path, method: str, run: str, record: dict, policy: Path | None) -> Path:
    folder = root / "submissions" / method / "runs" / run
    folder.mkdir(parents=True)
    (folder / "run.json").write_text(json.dumps(record))
    if policy is not None:
        shutil.copyfile(policy, folder / "policy.zip")
    return folder


def ppo_method(root: Path, runs: dict[str, Path] = PPO_RUNS) -> Path:
    """The method 'ppo': a learned method with a run per policy of `runs`."""
    data = {
        "name": "PPO",
        "authors": ["A. Person"],
        "algorithm": "PPO",
        "action_mode": "discrete",
        "tracks": ["single"],
        "recipe": RECIPE,
        "licence": "MIT",
    }
    folder = write_submission(root, "ppo", data)
    for seed, (name, policy) in enumerate(runs.items()):
        write_run(root, "ppo", name, run_record(seed), policy)
    return folder


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Path:
    """pd, random (built-ins) and ppo (three runs, zips), built with one worker."""
    root = tmp_path_factory.mktemp("board") / "leaderboards"
    write_submission(root, "pd", submission())
    write_submission(root, "random", submission(name="Random", builtin="random"))
    ppo_method(root)
    leaderboard.build(root, BOARD, workers=1)
    return root


@pytest.fixture
def board(built, tmp_path) -> Path:
    """A copy of the built board to change."""
    return Path(shutil.copytree(built, tmp_path / "leaderboards"))


def methods_of(document: dict, track: str) -> list[dict]:
    return next(t for t in document["tracks"] if t["track"] == track)["methods"]


def files(root: Path) -> dict[str, bytes]:
    return {
        str(path.relative_to(root)): path.read_bytes()
        for path in sorted(root.rglob("*"))
        if path.is_file()
    }


def test_builds_are_byte_identical_twice_and_with_two_workers(built, board, tmp_path):
    again = leaderboard.build(board, BOARD, workers=1)
    assert again.played == 0  # every result stored
    assert files(board) == files(built)
    fresh = tmp_path / "fresh"
    shutil.copytree(built / "submissions", fresh / "submissions")
    rebuilt = leaderboard.build(fresh, BOARD, workers=2, cache=False)
    assert rebuilt.played == rebuilt.episodes == EPISODES
    assert files(fresh) == files(built)


def test_each_results_file_is_what_bbbench_eval_writes(built):
    for slug, policy in [("pd", "pd"), ("ppo-s0", str(REFERENCE_POLICY))]:
        policy = load_policy(policy)
        fitting = [task for task in BOARD.tasks if policy.mismatch(task) is None]
        evaluation = evaluate(policy, fitting, episodes=BOARD.episodes, workers=1)
        written = (built / "results" / f"{slug}.json").read_text()
        assert written.replace('"policy.zip"', '"reference.zip"') == dumps(evaluation.document)


def registry() -> referencing.Registry:
    resources = [
        referencing.Resource.from_contents(json.loads((DOCS / name).read_text()))
        for name in ("submission-schema.json", "results-schema.json", "run-schema.json")
    ]
    return referencing.Registry().with_resources((r.id(), r) for r in resources)


def test_every_generated_document_and_submission_follows_its_schema(built):
    schema = json.loads((DOCS / "leaderboard-schema.json").read_text())
    document = json.loads((built / "bbbench-v0.json").read_text())
    jsonschema.Draft202012Validator(schema, registry=registry()).validate(document)
    results = json.loads((DOCS / "results-schema.json").read_text())
    profiles = json.loads((DOCS / "profile-schema.json").read_text())
    for path in (built / "results").glob("*.json"):
        kind = profiles if is_profile(path.name) else results
        jsonschema.validate(json.loads(path.read_text()), kind)
    assert len(list((built / "results").glob("*.profile.json"))) == 9
    assert len(list((built / "results").glob("*.sizes.json"))) == 2  # pd and random, multi
    method_schema = json.loads((DOCS / "submission-schema.json").read_text())
    for path in (built / "submissions").glob("*/submission.json"):
        jsonschema.validate(json.loads(path.read_text()), method_schema)
    run_schema = json.loads((DOCS / "run-schema.json").read_text())
    for path in (built / "submissions").glob("*/runs/*/run.json"):
        jsonschema.validate(json.loads(path.read_text()), run_schema)
    assert [track["track"] for track in document["tracks"]] == ["single", "multi", "cooperative"]
    single = document["tracks"][0]
    assert [(t["task"], t["ranked"]) for t in single["tasks"]] == [
        ("bbbench/Bumps-v1", True),
        ("bbbench/Bumps-v0", False),
        ("bbbench/FlatBalance-v0", True),
    ]
    assert {m["slug"] for m in single["methods"]} == {"pd", "ppo", "random"}
    assert [m["slug"] for m in methods_of(document, "multi")] == ["pd", "random"]
    assert [m["slug"] for m in methods_of(document, "cooperative")] == ["pd", "random"]
    ppo = next(m for m in single["methods"] if m["slug"] == "ppo")
    assert [run["slug"] for run in ppo["runs"]] == ["ppo-s0", "ppo-s1", "ppo-s2"]
    assert [run["training_seed"] for run in ppo["runs"]] == [0, 1, 2]


def test_a_multi_bot_tracks_methods_carry_their_team_size_profiles(built):
    document = json.loads((built / "bbbench-v0.json").read_text())
    for track in ("multi", "cooperative"):
        for method in methods_of(document, track):
            sizes = method["team_sizes"]
            if track == "cooperative":  # a beam takes 2 to 4 bots: no profile
                assert sizes is None
                continue
            assert sizes["task"] == "bbbench/MultiBalance-v1"
            assert sizes["trained_with"] is None  # controllers: no training size
            assert [point[0] for point in sizes["points"]] == [2, 3]
            (run,) = method["runs"]
            stored = json.loads((built / run["team_sizes"]["profile"]).read_text())
            (block,) = stored["axes"]
            assert [p["aggregate"]["normalized_score"] for p in block["points"]] == [
                point[1] for point in sizes["points"]
            ]
    readme = (built / "README.md").read_text()
    assert "Team sizes on MultiBalance-v1" in readme
    assert "| name | 2 bots | 3 bots |" in readme
    assert "Team sizes on MultiBalance-v1" in (built / "index.html").read_text()


def test_the_repository_board_follows_the_schemas():
    root = Path(__file__).parent.parent / "leaderboards"
    schema = json.loads((DOCS / "leaderboard-schema.json").read_text())
    document = json.loads((root / "bbbench-v0.json").read_text())
    jsonschema.Draft202012Validator(schema, registry=registry()).validate(document)
    for folder in sorted((root / "submissions").iterdir()):
        read_method(folder)  # bbbench's own checks pass too
    slugs = {m["slug"] for track in document["tracks"] for m in track["methods"]}
    assert {"pd", "lqr", "random"} <= slugs
    # The shipped policy is not a method: it trained on a superseded task, its wall time
    # unrecorded, with no logs in baselines/.
    assert "ppo-reference" not in slugs


def test_the_schemas_are_written_from_the_fields_bbbench_checks():
    for name, text in schema_files().items():
        assert (DOCS / name).read_text() == text, "run python scripts/submission_schemas.py"
    schema = json.loads((DOCS / "submission-schema.json").read_text())
    assert list(schema["properties"]) == list(METHOD_FIELDS)
    assert schema["properties"]["builtin"]["enum"] == list(bbbench.policies.BUILTIN_POLICIES)


def test_a_run_on_two_tracks_is_profiled_on_each_tracks_own_task(built):
    document = json.loads((built / "bbbench-v0.json").read_text())
    profiled = {
        (track["track"], run["slug"]): run["robustness"]
        for track in document["tracks"]
        for method in track["methods"]
        for run in method["runs"]
    }
    for slug in ("pd", "random"):
        single, multi = profiled["single", slug], profiled["multi", slug]
        assert single["task"] == "bbbench/VelocityTracking-v1"
        assert single["profile"] == f"results/{slug}.single.profile.json"
        assert multi["task"] == "bbbench/MultiBalance-v1"
        assert multi["profile"] == f"results/{slug}.multi.profile.json"
        team = profiled["cooperative", slug]
        assert team["task"] == "bbbench/BeamCarry-v0"
        assert team["profile"] == f"results/{slug}.cooperative.profile.json"

        # Each point is in the run's profile document; the board keeps its figures.
        def axes(run: dict) -> set[str]:
            profile = json.loads((built / run["profile"]).read_text())
            return {block["axis"] for block in profile["axes"]}

        assert axes(single) == axes(multi) == {"action_delay", "push"}
        assert axes(team) == {"action_delay", "push"}
        assert single["score"] != multi["score"] != team["score"]
    assert profiled["single", "ppo-s0"]["task"] == "bbbench/VelocityTracking-v1"
    ppo = next(m for m in methods_of(document, "single") if m["slug"] == "ppo")
    runs = [run["robustness"] for run in ppo["runs"]]
    assert ppo["robustness"]["score"] == pytest.approx(np.mean([r["score"] for r in runs]))
    assert ppo["robustness"]["worst_case"] == min(r["worst_case"] for r in runs)


def test_a_board_built_before_profiles_were_per_track_reuses_its_profiles(board):
    results = board / "results"
    for path in results.glob("*.single.profile.json"):  # as the old builds named them
        path.rename(results / path.name.replace(".single.profile.json", ".profile.json"))
    rebuilt = leaderboard.build(board, BOARD, workers=1)
    assert rebuilt.played == 0
    assert sorted(path.name for path in results.glob("*.profile.json")) == [
        "pd.cooperative.profile.json",
        "pd.multi.profile.json",
        "pd.single.profile.json",
        "ppo-s0.single.profile.json",
        "ppo-s1.single.profile.json",
        "ppo-s2.single.profile.json",
        "random.cooperative.profile.json",
        "random.multi.profile.json",
        "random.single.profile.json",
    ]
    assert leaderboard.check(board, BOARD, workers=1).problems == []


def test_check_passes_on_a_fresh_build(board):
    checked = leaderboard.check(board, BOARD, workers=1, spot=31)
    assert checked.problems == []
    assert checked.rescored == []
    # A budget of 31 episodes for the whole board, shared by its five runs: 6 each, and one
    # more for a run drawn at random.
    assert checked.spot_checked == checked.episodes == 31
    assert checked.entries == 5
    default = leaderboard.check(board, BOARD, workers=1)  # a budget above the board's size
    assert (
        default.spot_checked
        == sum(
            block["aggregate"]["episodes"]
            for path in (board / "results").glob("*.json")
            if not is_profile(path.name)
            for block in json.loads(path.read_text())["tasks"]
        )
        + 9 * 10 * 2
        + 2 * SIZES
    )  # every record: tasks, 9 profiles of 10 points of 2 episodes, and 2 team-size ones
    full = leaderboard.check(board, BOARD, workers=1, full=True)
    assert full.problems == []
    assert full.episodes == EPISODES


def forge(board: Path, slug: str, task_id: str, seed: int) -> None:
    """Change one recorded episode of `slug` and rebuild every number from the records, as
    a forger who knows the board's arithmetic would: only a replay can tell."""
    path = board / "results" / f"{slug}.json"
    document = read(path)
    block = next(block for block in document["tasks"] if block["task"] == task_id)
    record = next(record for record in block["episodes"] if record["seed"] == seed)
    record["return"] += 1.0
    path.write_text(dumps(document))
    leaderboard.build(board, BOARD, workers=1)  # aggregates, ranks, pages from the records


def test_a_forged_episode_is_caught_when_the_spot_check_draws_it(board):
    task_id, seed = "bbbench/FlatBalance-v0", bbbench.spec("bbbench/FlatBalance-v0").eval_seeds[2]
    forge(board, "pd", task_id, seed)
    every = leaderboard.check(board, BOARD, workers=1, spot=10_000)  # draws them all
    assert len(every.problems) == 1
    assert every.problems[0].startswith("1 of ")
    assert (
        "replayed episodes differ from their records, returns by at most 1 " in (every.problems[0])
    )
    assert f"(first: pd: {task_id} seed {seed}: recorded return " in every.problems[0]
    # Drawn at random: caught when its record is drawn (pd's 12 of its 80 here), and only
    # then.
    caught = []
    for draw in range(12):
        rng = np.random.default_rng(draw)
        problems = leaderboard.check(board, BOARD, workers=1, spot=60, rng=rng)
        caught.append(any(f"seed {seed}" in problem for problem in problems.problems))
    assert any(caught)
    assert not all(caught)


def test_a_tampered_aggregate_is_always_caught(board):
    path = board / "results" / "random.single.profile.json"
    document = json.loads(path.read_text())
    document["axes"][0]["points"][1]["aggregate"]["mean"] += 0.001
    path.write_text(dumps(document))
    for draw in range(2):
        problems = leaderboard.check(board, BOARD, workers=1, rng=np.random.default_rng(draw))
        assert len(problems.problems) == 1
        assert "random.single.profile.json.axes[" in problems.problems[0]
        assert ".aggregate.mean: checked in" in problems.problems[0]


def test_numbers_that_differ_are_said_in_one_line(board):
    """A machine that does not reproduce the board moves many numbers in the last bits:
    the check says how many, in how many files, and by how much, in one line."""
    for name in ("pd.json", "random.json"):
        path = board / "results" / name
        document = json.loads(path.read_text())
        for block in document["tasks"]:
            block["aggregate"]["mean"] += 2.8e-14
        path.write_text(dumps(document))
    (problem,) = leaderboard.check(board, BOARD, workers=1).problems
    assert problem.startswith("10 numbers in 2 files differ from the checked-in board, by at")
    assert "at most 2.84e-14 (first: results/pd.json.tasks[bbbench/Bumps-v0].aggregate.mean" in (
        problem
    )


def test_the_same_data_written_otherwise_is_named_as_formatting(board):
    path = board / "results" / "pd.json"
    path.write_text(json.dumps(json.loads(path.read_text()), indent=4) + "\n")
    (problem,) = leaderboard.check(board, BOARD, workers=1).problems
    assert problem == f"{path}: same data, other bytes (formatting)"


def test_a_board_made_on_another_build_is_checked_and_said(board, monkeypatch):
    """The platform block names the build a document was made on; it is not compared, and
    the check says which builds it set side by side."""
    here = leaderboard.checking.machine.record()
    elsewhere = {**here, "python": "3.13.0", "pybullet_build": "source"}
    monkeypatch.setattr(leaderboard.checking.machine, "record", lambda: elsewhere)
    checked = leaderboard.check(board, BOARD, workers=1)
    assert checked.problems == []
    assert checked.notes == [
        f"the board was built on Python {here['python']}, numpy {here['numpy']}, pybullet "
        f"{here['pybullet']} from its wheel; this check ran on Python 3.13.0, numpy "
        f"{here['numpy']}, pybullet {here['pybullet']} built from source, and reproduces it"
    ]
    monkeypatch.undo()  # the board is built again here, one episode forged
    task_id = "bbbench/FlatBalance-v0"
    forge(board, "pd", task_id, bbbench.spec(task_id).eval_seeds[0])
    monkeypatch.setattr(leaderboard.checking.machine, "record", lambda: elsewhere)
    problems = leaderboard.check(board, BOARD, workers=1, spot=10_000).problems
    assert problems[0] == (
        f"this check ran on Python 3.13.0, numpy {here['numpy']}, pybullet {here['pybullet']} "
        f"built from source; the board was built on Python {here['python']}, numpy "
        f"{here['numpy']}, pybullet {here['pybullet']} from its wheel. What differs (another "
        f"build, or another board):"
    )
    assert problems[1].startswith("1 of ")


def test_figures_are_compared_only_under_the_pinned_plotting_stack(board, monkeypatch):
    figure = board / "figures" / "single-per-task.svg"
    figure.write_text(figure.read_text().replace("<svg", "<svg data-other-matplotlib", 1))
    problems = leaderboard.check(board, BOARD, workers=1).problems
    assert problems == [
        f"{board}: figures missing or not as the rebuild draws them: figures/single-per-task.svg"
    ]
    monkeypatch.setitem(leaderboard.checking.PLOTTING_STACK, "matplotlib", "0.0.1")
    checked = leaderboard.check(board, BOARD, workers=1)
    assert checked.problems == []
    figures = 3 * 4  # three tracks, each with its four figures
    assert checked.notes == [
        f"{figures} figures not compared: they are drawn byte for byte by matplotlib 0.0.1 "
        f"only, and this is matplotlib {leaderboard.checking.plotting_stack()['matplotlib']}"
    ]


def test_the_page_shows_each_figure_from_its_own_file(board):
    page = (board / "index.html").read_text()
    assert "<svg" not in page
    figures = sorted((board / "figures").glob("*.svg"))
    assert len(figures) == 3 * 4
    for figure in figures:
        assert f'<img src="figures/{figure.name}"' in page
        svg = figure.read_text()
        assert svg.startswith("<svg")
        assert svg.endswith("</svg>\n")
        assert svg.count("<path") > 5


def test_the_pinned_plotting_stack_is_the_constraints_files():
    constraints = (Path(__file__).parents[1] / "constraints.txt").read_text().splitlines()
    pins = dict(line.split(";")[0].strip().split("==") for line in constraints if "==" in line)
    for package, version in leaderboard.checking.PLOTTING_STACK.items():
        assert pins[package] == version


def test_check_names_an_edited_number(board):
    path = board / "bbbench-v0.json"
    document = json.loads(path.read_text())
    runs = document["tracks"][0]["methods"][0]["runs"]
    runs[0]["tasks"]["bbbench/FlatBalance-v0"]["mean"] += 0.01
    path.write_text(dumps(document))
    problems = leaderboard.check(board, BOARD, workers=1).problems
    assert len(problems) == 1, problems
    method, run = document["tracks"][0]["methods"][0]["slug"], runs[0]["slug"]
    assert (
        f"tracks[single].methods[{method}].runs[{run}].tasks.bbbench/FlatBalance-v0.mean"
        in problems[0]
    )


def test_check_names_a_swapped_policy_file(board, tmp_path):
    other = tmp_path / "other.zip"
    PPO("MlpPolicy", bbbench.make("bbbench/FlatBalance-v0"), n_steps=64, device="cpu").save(other)
    shutil.copyfile(other, board / "submissions" / "ppo" / "runs" / "s1" / "policy.zip")
    checked = leaderboard.check(board, BOARD, workers=1)
    assert checked.rescored == ["ppo-s1"]  # a changed run is re-scored in full
    assert "ppo/runs/s1/policy.zip: SHA-256" in checked.problems[0]
    assert "the policy file changed" in checked.problems[0]
    assert len(checked.problems) > 1  # and what its re-score found differs


def test_check_names_a_submission_added_without_a_rebuild(board):
    write_submission(board, "twin", submission(name="Stand", builtin="stand"))
    checked = leaderboard.check(board, BOARD, workers=1)
    assert checked.rescored == ["twin"]
    assert "submissions/twin: a run that is not on the board" in checked.problems[0]
    assert any("results/twin.json: missing" in problem for problem in checked.problems)


def test_a_changed_submission_is_re_scored_in_full_even_after_a_rebuild_of_its_metadata(board):
    """The entry's recorded inputs key no longer matches: its stored episodes are not
    trusted, whatever the rest of the board says."""
    path = board / "submissions" / "pd" / "submission.json"
    path.write_text(json.dumps(submission(notes="trained longer")))
    document_path = board / "bbbench-v0.json"
    document = json.loads(document_path.read_text())
    for track in document["tracks"]:
        for method in track["methods"]:
            if method["slug"] == "pd":
                method["submission"]["notes"] = "trained longer"
    document_path.write_text(dumps(document))
    checked = leaderboard.check(board, BOARD, workers=1)
    assert checked.rescored == ["pd"]
    assert any(".inputs: checked in" in problem for problem in checked.problems)


def test_check_names_a_task_whose_behaviour_changed(board, monkeypatch):
    monkeypatch.setattr(TaskSpec, "fingerprint", property(lambda task: "0123456789abcdef"))
    problems = leaderboard.check(board, BOARD, workers=1).problems
    assert len(problems) == len(BOARD.tasks)
    assert all("fingerprint is now 0123456789abcdef" in problem for problem in problems)


def test_check_names_an_edited_page_and_a_stale_result_and_figure(board):
    page = board / "index.html"
    page.write_text(page.read_text().replace("bbbench leaderboard", "my leaderboard", 1))
    (board / "results" / "gone.json").write_text("{}")
    (board / "figures" / "gone-robustness.svg").write_text("<svg/>")
    problems = leaderboard.check(board, BOARD, workers=1).problems
    assert any("index.html: differs from the rebuild from line" in p for p in problems)
    assert any("gone.json: no run 'gone'" in p for p in problems)
    assert any("gone-robustness.svg: not drawn any more" in p for p in problems)
    leaderboard.build(board, BOARD, workers=1)
    assert not (board / "results" / "gone.json").exists()
    assert not (board / "figures" / "gone-robustness.svg").exists()


def test_add_plays_only_the_new_run(board):
    counted = []
    method = submission(name="Stand")
    run = {k: method.pop(k) for k in ("training_seed", "command", "wall_time", "hardware")}
    run["recipe"] = method.pop("recipe")
    del method["builtin"]
    built = leaderboard.add(
        board, "stand", "twin", method, run, board=BOARD, workers=1, on_episodes=counted.append
    )
    # stand on the 5 tasks, its 3 profiles and its team sizes on the multi-bot track
    assert built.played == sum(counted) == 5 * 4 + 3 * PROFILE + SIZES
    assert (board / "submissions" / "twin" / "submission.json").is_file()
    assert leaderboard.check(board, BOARD, workers=1).problems == []


def test_add_puts_a_run_beneath_its_method_and_refuses_another_recipe(board, tmp_path):
    exported = export_zip(load_policy(TERRAIN_POLICIES["ppo-slopes-v1"]), tmp_path / "s.onnx")
    leaderboard.add(board, str(exported), "ppo", {}, run_record(3), board=BOARD, workers=1)
    assert (board / "submissions" / "ppo" / "runs" / "s3" / "policy.onnx").is_file()
    document = json.loads((board / "bbbench-v0.json").read_text())
    ppo = next(m for m in methods_of(document, "single") if m["slug"] == "ppo")
    assert [run["slug"] for run in ppo["runs"]] == ["ppo-s0", "ppo-s1", "ppo-s2", "ppo-s3"]
    before = files(board)
    longer = run_record(4, recipe={**RECIPE, "world_steps": 800_000})
    slopes = str(TERRAIN_POLICIES["ppo-slopes-v1"])
    with pytest.raises(SubmissionError, match="recipe's 'world_steps' is 800000, the method's"):
        leaderboard.add(board, slopes, "ppo", {}, longer, board=BOARD, workers=1)
    with pytest.raises(SubmissionError, match="the method's 'name' is \"PPO\", the run's"):
        leaderboard.add(board, slopes, "ppo", {"name": "PPO 2"}, run_record(4), board=BOARD)
    assert files(board) == before


def test_one_policy_under_two_slugs_is_refused(command_board, capsys, tmp_path):
    """A board ranks policies, not copies: the same bytes, or a built-in on the board
    already, are refused in one line by `add`, and by `build` when written by hand."""
    err = leaderboard_exit_2(capsys, command_board, "add", "pd", "--slug", "pd-again", *ADD)
    assert "the built-in 'pd' (discrete) is on the board already, as 'pd'" in err
    err = leaderboard_exit_2(
        capsys, command_board, "add", str(REFERENCE_POLICY), "--slug", "copy", "--seed", "0", *ADD
    )
    assert f"{REFERENCE_POLICY}: the same policy bytes are on the board already, as 'ppo-s0'" in (
        err
    )
    assert not (command_board / "submissions" / "copy").exists()
    write_submission(command_board, "twin", submission(name="Twin"))
    err = leaderboard_exit_2(capsys, command_board, "build")
    assert "submissions/twin: the built-in 'pd' (discrete) as 'pd' already" in err


def test_an_interrupted_build_changes_nothing(board, monkeypatch):
    before = files(board)
    write_submission(board, "twin", submission(name="Stand", builtin="stand"))

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(leaderboard.board, "evaluate", interrupted)
    with pytest.raises(KeyboardInterrupt):
        leaderboard.build(board, BOARD, workers=1)
    after = files(board)
    del after["submissions/twin/submission.json"]
    assert after == before


def test_probability_of_improvement_is_the_pairwise_win_rate():
    rng = np.random.default_rng(0)
    x, y = rng.normal(size=30), rng.normal(0.3, size=40)
    y[:5] = x[:5]  # ties count half
    wins = np.mean([[1.0 if a > b else 0.5 if a == b else 0.0 for b in y] for a in x])
    point, (low, high) = stats.probability_of_improvement([x, x], [y, y])
    assert point == pytest.approx(wins)
    assert low < point < high
    assert stats.probability_of_improvement([x], [x])[0] == 0.5


# -- the command --------------------------------------------------------------------


@pytest.fixture
def command_board(board, monkeypatch) -> Path:
    monkeypatch.setattr(leaderboard, "DEFAULT_BOARD", BOARD)
    return board


def leaderboard_exit_2(capsys, root: Path, *argv: str) -> str:
    before = files(root)
    code = main(["leaderboard", *argv, "--root", str(root), "--workers", "1"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith("bbbench: error:"), err
    assert len(err.strip().splitlines()) == 1, err
    assert files(root) == before  # nothing written
    return err


ADD = [
    "--name", "X", "--algorithm", "PPO", "--author", "A", "--track", "single",
    "--world-steps", "10", "--recipe", "r.yml", "--wall-time", "1 min", "--hardware", "laptop",
    "--command", "train.py", "--licence", "MIT",
]  # fmt: skip


def test_show_prints_the_ranked_tables(command_board, capsys):
    assert main(["leaderboard", "show", "--root", str(command_board), "--track", "multi"]) == 0
    out = capsys.readouterr().out
    assert "Multi-bot tasks" in out
    assert "Single-bot" not in out
    assert out.index("PD baseline") < out.index("Random")


def test_build_and_check_from_the_command(command_board, capsys):
    assert main(["leaderboard", "build", "--root", str(command_board), "--workers", "1"]) == 0
    episodes = EPISODES
    assert f"{episodes} episodes (0 played, {episodes} from stored results)" in (
        capsys.readouterr().out
    )
    assert main(["leaderboard", "check", "--root", str(command_board), "--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("leaderboard check ok: 5 runs, 5 tasks; every number recomputed")
    # Every record of this small board (260): the budget, 1,000, is more.
    assert "re-scored in full (inputs changed): none; 260 episodes of the others replayed" in out
    assert "(a budget of 1000 shared by the runs)" in out
    assert main(["leaderboard", "check", "--root", str(command_board), "--full"]) == 0
    assert f"{episodes} episodes played again" in capsys.readouterr().out
    (command_board / "README.md").write_text("edited\n")
    assert main(["leaderboard", "check", "--root", str(command_board), "--workers", "1"]) == 1
    assert "README.md: differs from the rebuild from line 1" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        ("{not json", "pd/submission.json: not valid JSON"),
        (json.dumps(submission(extra=1)), "unknown field 'extra'"),
        (json.dumps(submission(licence=None)), "missing field 'licence'"),
        (json.dumps(submission(recipe={"world_steps": -1})), "field 'recipe.world_steps'"),
        (json.dumps(submission(tracks=["solo"])), "field 'tracks': 'solo' is not one of the"),
        (json.dumps(submission(authors=[])), "field 'authors': expected a non-empty list"),
        (json.dumps(submission(action_mode="both")), "field 'action_mode': expected one of"),
        (json.dumps(submission(url="javascript:x")), "field 'url': expected an http(s) URL"),
        ('{"name": "a", "name": "b"}', "the field 'name' is given twice"),
    ],
)
def test_a_malformed_submission_is_exit_2_naming_file_and_field(
    command_board, capsys, content, expected
):
    (command_board / "submissions" / "pd" / "submission.json").write_text(content)
    assert expected in leaderboard_exit_2(capsys, command_board, "build")


def test_stray_files_and_unsafe_folder_names_are_refused(command_board, capsys):
    (command_board / "submissions" / "pd" / "run.py").write_text("print('hi')")
    assert "pd/run.py: not part of a submission" in leaderboard_exit_2(
        capsys, command_board, "build"
    )
    (command_board / "submissions" / "pd" / "run.py").unlink()
    moved = command_board / "submission.json"
    (command_board / "submissions" / "pd" / "submission.json").rename(moved)
    assert "pd/submission.json: missing" in leaderboard_exit_2(capsys, command_board, "build")
    moved.rename(command_board / "submissions" / "pd" / "submission.json")
    shutil.copytree(command_board / "submissions" / "pd", command_board / "submissions" / "P D")
    assert "is not a safe folder name" in leaderboard_exit_2(capsys, command_board, "check")


@pytest.mark.parametrize(
    ("policy", "slug", "expected"),
    [
        ("pd", "../evil", "slug '../evil' is not a safe folder name"),
        ("stand", "pd", "the method 'pd' is one run in its own folder, with no room"),
        ("nothing.zip", "new", "nothing.zip: no such file, and not a built-in policy"),
    ],
)
def test_add_refuses_bad_slugs_and_missing_policies(command_board, capsys, policy, slug, expected):
    err = leaderboard_exit_2(capsys, command_board, "add", policy, "--slug", slug, *ADD)
    assert expected in err


def test_add_refuses_a_hostile_zip_and_runs_none_of_it(command_board, capsys, tmp_path, marker):
    hostile = rewrite(
        REFERENCE_POLICY,
        tmp_path / "hostile.zip",
        lambda data: data.update(policy_class=pickled(marker)),
    )
    err = leaderboard_exit_2(capsys, command_board, "add", str(hostile), "--slug", "new", *ADD)
    assert str(hostile) in err
    assert not marker.exists()
    assert not (command_board / "submissions" / "new").exists()


def test_add_refuses_an_oversized_file(command_board, capsys, tmp_path):
    big = tmp_path / "big.zip"
    big.write_bytes(b"\0" * (leaderboard.MAX_POLICY_BYTES + 1))
    err = leaderboard_exit_2(capsys, command_board, "add", str(big), "--slug", "new", *ADD)
    assert "big.zip: 5.0 MB, over the 5 MB cap" in err


def test_add_refuses_a_wrong_action_mode_and_a_policy_that_fits_no_task(
    command_board, capsys, tmp_path
):
    argv = ["--slug", "new", *ADD]
    err = leaderboard_exit_2(
        capsys, command_board, "add", str(REFERENCE_POLICY), "--action-mode", "continuous", *argv
    )
    assert "field 'action_mode' is 'continuous', but the policy acts in discrete mode" in err
    cartpole = tmp_path / "cartpole.zip"
    PPO("MlpPolicy", gym.make("CartPole-v1"), n_steps=64, device="cpu").save(cartpole)
    err = leaderboard_exit_2(capsys, command_board, "add", str(cartpole), *argv)
    assert "cartpole.zip" in err
    assert "fits no task of the suite" in err


def test_the_metadata_of_an_added_run_is_checked_like_a_written_one(board):
    with pytest.raises(SubmissionError, match=r"field 'recipe\.world_steps'"):
        leaderboard.add(
            board, "stand", "new", {}, run_record(None, recipe={**RECIPE, "world_steps": "many"})
        )


# -- a method is its runs -----------------------------------------------------------


def test_a_method_scores_every_episode_of_every_run(built):
    """A run's score on a task is its mean normalized score, falls included; the method's
    is the mean over runs x tasks; a rank counts the methods that beat it."""
    document = json.loads((built / "bbbench-v0.json").read_text())
    track = document["tracks"][0]
    counted = [t["task"] for t in track["tasks"] if t["overall"]]
    ppo = next(m for m in track["methods"] if m["slug"] == "ppo")
    per_run = [
        np.mean(
            [
                run["tasks"][task_id]["normalized_score"]  # of the mean return: every episode
                for task_id in counted
            ]
        )
        for run in ppo["runs"]
    ]
    assert ppo["overall"]["statistic"] == "mean"
    assert ppo["overall"]["normalized_score"] == pytest.approx(np.mean(per_run), abs=1e-12)
    low, high = ppo["overall"]["normalized_ci"]
    assert low <= ppo["overall"]["normalized_score"] <= high
    assert min(per_run) < high
    assert max(per_run) > low
    for method in track["methods"]:
        assert method["rank"] == 1 + len(method["beaten_by"])
        assert method["unranked"] is None


def test_a_task_the_controller_and_most_methods_solve_leaves_the_overall(built):
    document = json.loads((built / "bbbench-v0.json").read_text())
    for track in document["tracks"]:
        for task in track["tasks"]:
            scores = [
                m["tasks"][task["task"]]["normalized_score"]
                for m in track["methods"]
                if task["task"] in m["tasks"]
            ]
            pd_score = next(m for m in track["methods"] if m["slug"] == "pd")["tasks"][
                task["task"]
            ]["normalized_score"]
            solved = sum(score >= 0.95 for score in scores)
            rule = task["ranked"] and pd_score >= 0.95 and 2 * solved > len(scores)
            assert task["saturated"] == rule
            assert task["overall"] == (task["ranked"] and not rule)


def test_a_learned_method_of_two_runs_is_listed_not_ranked(board):
    shutil.rmtree(board / "submissions" / "ppo" / "runs" / "s2")
    document = leaderboard.build(board, BOARD, workers=1).document
    ppo = next(m for m in methods_of(document, "single") if m["slug"] == "ppo")
    assert ppo["rank"] is None
    assert ppo["unranked"] == "2 runs; a learned method ranks from 3"
    assert methods_of(document, "single")[-1]["slug"] == "ppo"  # after the ranked ones
    assert "- PPO: 2 runs; a learned method ranks from 3" in (board / "README.md").read_text()


def test_a_method_that_plays_some_of_a_tracks_tasks_is_not_ranked_on_it(board):
    built = leaderboard.generate(board, BOARD, workers=1)
    for entry in built.scored:  # as if pd fit FlatBalance-v0 only
        if entry.run.slug == "pd":
            entry.results["tasks"] = [
                b for b in entry.results["tasks"] if b["task"] != "bbbench/Bumps-v1"
            ]
    methods = read_methods(board / "submissions")
    document = leaderboard_document(methods, built.scored, BOARD)
    pd = next(m for m in methods_of(document, "single") if m["slug"] == "pd")
    assert pd["rank"] is None
    assert pd["unranked"] == "plays 1 of the track's 2 tasks"
    assert pd["overall"] == {"tasks": 0}
    assert "bbbench/Bumps-v1" not in pd["tasks"]


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (
            lambda runs: (runs / "s1" / "run.json").write_text(
                json.dumps(run_record(1, recipe={**RECIPE, "file": "other.yml"}))
            ),
            "runs/s1/run.json: its recipe's 'file' is \"other.yml\", the method's \"sb3 "
            'defaults"; runs of one method share its recipe',
        ),
        (
            lambda runs: (runs / "s2" / "run.json").write_text(json.dumps(run_record(1))),
            "runs/s2/run.json: training seed 1 is s1's too",
        ),
        (lambda runs: (runs / "s1" / "policy.zip").unlink(), "runs/s1: no policy.zip or"),
        (lambda runs: (runs / "s1" / "run.json").unlink(), "runs/s1/run.json: missing"),
    ],
)
def test_a_method_whose_runs_disagree_or_lack_a_file_is_exit_2(
    command_board, capsys, change, expected
):
    change(command_board / "submissions" / "ppo" / "runs")
    assert expected in leaderboard_exit_2(capsys, command_board, "build")


# -- the page, in a real browser (headless Chromium; .ci/run installs it) -----------


def rows_of(table) -> list[str]:
    return [
        body.get_attribute("data-slug") for body in table.find_elements("css selector", "tbody")
    ]


def test_the_page_ranks_sorts_details_and_plots_in_a_browser(chromium, board):
    from selenium.webdriver.support.wait import WebDriverWait

    hostile = submission(
        name="<img src=x onerror=alert(1)>", notes="</script><b>bold</b>", builtin="stand"
    )
    write_submission(board, "hostile", hostile)
    document = leaderboard.build(board, BOARD, workers=1).document
    chromium.get((board / "index.html").as_uri())
    for track in document["tracks"]:
        table = chromium.find_element("id", f"table-{track['track']}")
        assert rows_of(table) == [entry["slug"] for entry in track["methods"]]
        headers = table.find_elements("css selector", "th")
        name = next(h for h in headers if h.text == "Name")
        name.click()
        expected = sorted(track["methods"], key=lambda e: e["submission"]["name"].lower())
        assert rows_of(table) == [entry["slug"] for entry in expected]
        assert name.get_attribute("aria-sort") == "ascending"
        name.click()
        assert rows_of(table) == [entry["slug"] for entry in reversed(expected)]
        headers[0].click()  # rank, ascending
        assert rows_of(table) == [entry["slug"] for entry in track["methods"]]
        method = table.find_element("css selector", "tbody[data-slug=hostile]")
        row = method.find_element("css selector", "tr.entry")
        details = method.find_element("css selector", "tr.details")
        assert not details.is_displayed()
        row.click()
        assert details.is_displayed()
        assert "</script><b>bold</b>" in details.text  # shown as text, not markup
        assert "<img src=x onerror=alert(1)>" in row.text
        for plot in ("interval-estimates", "performance-profiles", "per-task", "robustness"):
            figure = chromium.find_element("id", f"{track['track']}-{plot}")
            image = figure.find_element("css selector", "img")
            chromium.execute_script("arguments[0].scrollIntoView()", image)  # loaded lazily
            WebDriverWait(chromium, 10).until(
                lambda driver, image=image: driver.execute_script(
                    "return arguments[0].complete", image
                )
            )
            assert chromium.execute_script("return arguments[0].naturalWidth", image) > 200
            assert image.size["width"] > 200
            assert image.size["height"] > 100
    errors = [e for e in chromium.get_log("browser") if e["level"] == "SEVERE"]
    assert errors == []


def test_texts_with_terminal_escapes_are_refused(board):
    data = submission(name="\x1b[2J\x1b[31mred")
    (board / "submissions" / "pd" / "submission.json").write_text(json.dumps(data))
    with pytest.raises(SubmissionError, match="field 'name': expected text without control"):
        leaderboard.build(board, BOARD, workers=1)
    schema = json.loads((DOCS / "submission-schema.json").read_text())
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(data, schema)


def test_a_build_on_ray_writes_the_same_bytes(built, tmp_path):
    pytest.importorskip("ray", reason="the Ray backend is an extra: pip install 'bbbench[ray]'")
    fresh = tmp_path / "on-ray"
    shutil.copytree(built / "submissions", fresh / "submissions")
    leaderboard.build(fresh, BOARD, workers=2, backend="ray", cache=False)
    assert files(fresh) == files(built)


def test_the_projects_readme_gets_the_baselines_table_and_check_guards_it(board):
    from bbbench.leaderboard.views import BASELINES_END, BASELINES_START

    readme = board.parent / "README.md"
    readme.write_text(f"# Project\n\n{BASELINES_START}\nstale\n{BASELINES_END}\n\nMore.\n")
    leaderboard.build(board, BOARD, workers=1)
    text = readme.read_text()
    assert "stale" not in text
    assert text.startswith("# Project\n")
    assert text.endswith(f"{BASELINES_END}\n\nMore.\n")
    table = text[text.index(BASELINES_START) : text.index(BASELINES_END)]
    assert "| 1 | PD baseline |" in table
    assert "Bumps-v0" not in table
    readme.write_text(text.replace("| 1 | PD baseline |", "| 1 | PD champion |"))
    problems = leaderboard.check(board, BOARD, workers=1).problems
    assert len(problems) == 1
    assert "README.md: differs from the rebuild" in problems[0]


def test_an_onnx_export_of_a_zip_enters_with_the_zips_own_episodes(board, tmp_path):
    exported = export_zip(load_policy(REFERENCE_POLICY), tmp_path / "reference.onnx")
    method = {"name": "PPO (ONNX)", "algorithm": "PPO", "authors": ["A"], "licence": "MIT"}
    method["tracks"] = ["single"]
    leaderboard.add(board, str(exported), "ppo-onnx", method, run_record(0), board=BOARD)
    assert (board / "submissions" / "ppo-onnx" / "runs" / "s0" / "policy.onnx").is_file()
    mine = json.loads((board / "results" / "ppo-onnx-s0.json").read_text())
    zips = json.loads((board / "results" / "ppo-s0.json").read_text())
    assert mine["policy"]["format"] == "onnx"
    assert [t["episodes"] for t in mine["tasks"]] == [t["episodes"] for t in zips["tasks"]]
    assert leaderboard.check(board, BOARD, workers=1).problems == []

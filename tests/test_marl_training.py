"""`bbbench train TASK --algo ippo|mappo`: BenchMARL recipes, trained for real (a few
hundred world steps), the last policy exported to ONNX with its contract, the same bytes
from the same seed in another process and with any number of worker processes, and bad
recipes refused in one line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import bbbench
from bbbench.cli import main
from bbbench.policies import classical_controller, load_policy
from bbbench.tasks.suite import agent_layout
from bbbench.training import MARL_TRAINABLE, recipe, trainable
from bbbench.training.recipe_files import recipe_file
from bbbench.training.sb3.recipes import recipes
from conftest import load_script, one_line_exit_2

TASK = "bbbench/BeamCarry-v0"
MIXED = "bbbench/MixedBeamCarry-v0"
# A recipe for tests: BenchMARL iterations of 200 world steps from 2 worlds, one pass of two
# minibatches.
SMALL = """\
bbbench/BeamCarry-v0:
  algorithm: {lmbda: 0.95}
  model: {name: neighbour_encoder, embed: 8, hidden: [16]}
  critic_model: {name: mlp, num_cells: [16]}
  experiment:
    lr: 0.001
    on_policy_collected_frames_per_batch: 200
    on_policy_n_envs_per_worker: 2
    on_policy_n_minibatch_iters: 1
    on_policy_minibatch_size: 100
"""
TRAIN = ["--steps", "400", "--eval-episodes", "2"]


def small_recipe(tmp_path: Path, text: str = SMALL) -> str:
    path = tmp_path / "recipe.yml"
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize("algorithm", MARL_TRAINABLE)
def test_every_shipped_marl_recipe_reads_and_builds_its_configs(algorithm):
    import yaml

    table = yaml.safe_load(recipe_file(algorithm).read_text())
    # A recipe for every latest multi-bot and team task (the recurrent ones: for those of
    # one robot; a team file carries no recurrent state), and for none other.
    latest = bbbench.list_tasks(multi_agent=True, latest=True)
    if trainable(algorithm).recurrent:
        latest = [t for t in latest if not bbbench.spec(t).mixed]
    assert sorted(table) == latest
    for task_id in table:
        plan = recipe(algorithm, task_id)
        assert plan.algorithm_config().entropy_coef == 0.0
        assert plan.model_config() is not None
        assert plan.model_config(critic=True) is not None
        assert plan.task_config().task_id == task_id
        # The field's budget and batches (BenchMARL's defaults): 3M world steps, batches
        # of 6,000 from 10 worlds, in worker processes.
        assert plan.n_timesteps == 3_000_000
        assert plan.batch() >= 6000
        assert plan.n_envs >= 10
        # Worker processes step the batched env's worlds (a mixed team's too).
        assert plan.task_config().config["workers"] == 2


def test_the_sb3_recipe_table_does_not_take_a_marl_algorithm():
    with pytest.raises(ValueError, match="mappo trains with BenchMARL"):
        recipes("mappo")


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["bbbench/FlatBalance-v1", "--algo", "mappo"], "is a single-bot task: MAPPO trains"),
        (["bbbench/BeamCarry-v0", "--algo", "qmix"], "unknown algorithm 'qmix'"),
        (
            ["bbbench/MixedBeamCarry-v0", "--algo", "ippo", "--action-mode", "discrete"],
            "is a mixed team (wheel-legged and two-wheel robots): IPPO trains the continuous",
        ),
        (["bbbench/MixedBeamCarry-v0", "--algo", "mappo", "--out", "p.onnx"], "ending in .zip"),
        (
            ["bbbench/MixedBeamCarry-v0", "--algo", "ippo-gru"],
            "no recurrent state: train it with ippo",
        ),
        (["bbbench/BeamCarry-v0", "--algo", "ippo", "--out", "p.zip"], "ending in .onnx"),
        (
            ["bbbench/BeamCarry-v0", "--algo", "ippo", "--action-mode", "continuous"],
            "discrete actions (Discrete(9) on bbbench/BeamCarry-v0): drop --action-mode, or give a",
        ),
        (
            ["bbbench/Swap-v0", "--algo", "ippo", "--action-mode", "continuous"],
            "discrete actions (Discrete(27) on bbbench/Swap-v0)",
        ),
        (["bbbench/MultiBalance-v0", "--algo", "ippo"], "bbbench/MultiBalance-v1"),
        (["bbbench/BeamCarry-v0", "bbbench/Convoy-v0", "--algo", "ippo"], "one multi-bot task"),
        (["bbbench/BeamCarry-v0", "--algo", "ippo", "--steps", "0"], "--steps"),
    ],
)
def test_a_marl_request_that_cannot_train_exits_2(tmp_path, capsys, monkeypatch, argv, expected):
    monkeypatch.chdir(tmp_path)
    assert expected in one_line_exit_2(capsys, "train", *argv)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (("name: neighbour_encoder", "name: gnn"), "unknown model 'gnn'"),
        (("algorithm: {lmbda: 0.95}", "algorithm: {name: qmix}"), "unknown algorithm 'qmix'"),
        (("algorithm: {lmbda: 0.95}", "algorithm: {name: mappo}"), "the recipe is mappo's"),
        (("algorithm: {lmbda: 0.95}", "algorithm: {lambda: 0.95}"), "Did you mean 'lmbda'?"),
        (("algorithm: {lmbda: 0.95}", "algorithm: {entropy_coef: 0.01}"), "entropy_coef must be 0"),
        (("lr: 0.001", "loggers: [wandb]"), "loggers is bbbench train's"),
        (("lr: 0.001", "learning_rate: 0.001"), "unknown key 'learning_rate'"),
        (("critic_model: {name: mlp, num_cells: [16]}", "critic_model: {}"), "give its name"),
        (("hidden: [16]", "hidden: [16], depth: 3"), "takes embed, hidden, pool"),
        (("experiment:", "teams: 2\n  experiment:"), "unknown section 'teams'"),
        (("embed: 8,", "embed: 8, pool: sum,"), "pool 'sum'"),
        (("{name: mlp, num_cells: [16]}", "{name: mlp, layer_class: torch.nn.Conv1d}"), "Linear"),
        (("frames_per_batch: 200", "frames_per_batch: 1"), "less than one step per world"),
        (("algorithm:", "task: {workers: 0}\n  algorithm:"), "workers 0"),
        (("algorithm:", "task: {workers: two}\n  algorithm:"), "whole number"),
        (("lr: 0.001", "prefer_continuous_actions: 1"), "must be true or false, got 1"),
    ],
)
def test_a_bad_marl_recipe_exits_2_with_one_line(tmp_path, capsys, change, expected):
    text = SMALL.replace(*change)
    assert text != SMALL
    out = tmp_path / "policy.onnx"
    argv = ["train", TASK, "--algo", "ippo", "--recipe", small_recipe(tmp_path, text)]
    assert expected in one_line_exit_2(capsys, *argv, "--out", str(out))
    assert not out.exists()


def test_a_recipe_chooses_the_action_mode_the_task_and_the_export_allow(tmp_path):
    """BenchMARL's `prefer_continuous_actions` is the recipe's choice: continuous on a
    robot that takes both modes; refused where the task or the export cannot follow it."""
    import yaml

    from bbbench.training.benchmarl.recipes import marl_recipe

    continuous = SMALL.replace("lr: 0.001", "lr: 0.001\n    prefer_continuous_actions: true")
    plan = marl_recipe("ippo", TASK, small_recipe(tmp_path, continuous))
    assert plan.action_mode == "continuous"
    assert plan.experiment_config(400, 2, tmp_path).prefer_continuous_actions is True
    assert marl_recipe("ippo", TASK, small_recipe(tmp_path)).action_mode == "discrete"
    assert recipe("ippo", MIXED).action_mode == "continuous"
    refused = SMALL.replace(TASK, MIXED).replace(
        "lr: 0.001", "lr: 0.001\n    prefer_continuous_actions: false"
    )
    with pytest.raises(ValueError, match="is a mixed team, whose robots share continuous"):
        marl_recipe("ippo", MIXED, small_recipe(tmp_path, refused))
    table = yaml.safe_load(recipe_file("ippo-gru").read_text())
    table["bbbench/Swap-v0"]["experiment"]["prefer_continuous_actions"] = True
    (tmp_path / "gru.yml").write_text(yaml.safe_dump(table))
    with pytest.raises(ValueError, match="exports discrete actions only"):
        marl_recipe("ippo-gru", "bbbench/Swap-v0", tmp_path / "gru.yml")


@pytest.mark.parametrize(
    ("flags", "expected"),
    [
        (["--workers", "0"], "--workers 0"),
        (["--workers", "3"], "more worker processes than the 2 worlds"),
        (["--n-envs", "300"], "less than one step per world"),
        (["--n-envs", "100000000"], "more than this machine's"),
    ],
)
def test_bad_worlds_or_workers_exit_2_with_one_line(tmp_path, capsys, flags, expected):
    out = tmp_path / "policy.onnx"
    argv = ["train", TASK, "--algo", "ippo", "--recipe", small_recipe(tmp_path), *flags]
    assert expected in one_line_exit_2(capsys, *argv, "--out", str(out))
    assert not out.exists()


def test_workers_belong_to_the_marl_algorithms(tmp_path, capsys):
    argv = ["train", "bbbench/FlatBalance-v1", "--algo", "ppo", "--workers", "2"]
    assert "--n-envs" in one_line_exit_2(capsys, *argv, "--out", str(tmp_path / "p.zip"))


@pytest.mark.slow
@pytest.mark.parametrize("algorithm", ["ippo", "ppo"])
def test_a_budget_below_one_batch_trains_one_batch_says_so_and_evaluates_once(
    tmp_path, capsys, algorithm
):
    """--steps 10 is rounded up to one batch (IPPO: 200 world steps of the recipe; PPO on
    MultiBalance-v1: 512 steps of each of its 2 worlds' 4 bots), said on stderr, and
    evaluated once, at its end."""
    out = tmp_path / ("policy.onnx" if algorithm == "ippo" else "policy.zip")
    argv = ["train", TASK, "--algo", "ippo", "--recipe", small_recipe(tmp_path)]
    if algorithm == "ppo":
        argv = ["train", "bbbench/MultiBalance-v1", "--algo", "ppo"]
    code = main([*argv, "--steps", "10", "--out", str(out), "--eval-episodes", "1"])
    err = capsys.readouterr().err
    assert code == 0, err
    batch = 200 if algorithm == "ippo" else 512 * 2 * 4
    assert f"--steps 10 is less than one batch of the recipe ({batch:,} steps" in err
    points = json.loads((tmp_path / "curve.json").read_text())["points"]
    assert [point["steps"] for point in points] == [batch]


def test_mappo_refuses_a_critic_that_is_not_centralised(tmp_path, capsys):
    text = SMALL.replace(
        "critic_model: {name: mlp, num_cells: [16]}", "critic_model: {name: neighbour_encoder}"
    )
    argv = ["train", TASK, "--algo", "mappo", "--recipe", small_recipe(tmp_path, text)]
    assert "centralised" in one_line_exit_2(capsys, *argv, "--out", str(tmp_path / "p.onnx"))


def test_without_benchmarl_a_marl_algorithm_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "bbbench.training.benchmarl.recipes", None)  # import fails
    with pytest.raises(ValueError, match=r"pip install 'bbbench\[marl\]'"):
        recipe("mappo", TASK)


def bbbench_cli(*argv: str) -> None:
    """`bbbench ARGV` in a process of its own."""
    subprocess.run([sys.executable, "-m", "bbbench", *argv], check=True, capture_output=True)


def untimed(curve: Path) -> list[dict]:
    points = json.loads(curve.read_text())["points"]
    return [{k: v for k, v in point.items() if k != "wall_time_s"} for point in points]


@pytest.mark.slow
def test_a_mixed_team_trains_a_policy_per_robot_into_one_team_file(tmp_path):
    """On a mixed team IPPO learns the continuous actions both robots take, a policy per
    robot, and writes a team file (`bbbench.policies.onnx.team`): the file its curve's
    last point played, the same bytes from the same seed in another process."""
    from bbbench.evaluation.episodes import LockstepPlayer
    from bbbench.policies.onnx.team import TeamFilePolicy
    from bbbench.training.logs import curve_point
    from bbbench.training.seeds import evaluation_seeds

    plan = small_recipe(tmp_path, SMALL.replace(TASK, MIXED))
    written = []
    for name in ("here", "there"):
        out = tmp_path / name / "policy.zip"
        out.parent.mkdir()
        argv = ["train", MIXED, "--algo", "ippo", "--recipe", plan, "--out", str(out), *TRAIN]
        if name == "here":
            assert main(argv) == 0
        else:
            bbbench_cli(*argv)
        written.append(out)
    assert written[0].read_bytes() == written[1].read_bytes()
    team = load_policy(written[0])
    assert isinstance(team, TeamFilePolicy)
    assert team.mismatch(MIXED) is None
    assert team.action_mode == "continuous"
    assert {group: policy.contract.training_steps for group, policy in team.groups.items()} == {
        "wheel-legged": 400,
        "two-wheel": 400,
    }
    record = json.loads((written[0].parent / "train.json").read_text())
    assert record["action_mode"] == "continuous"
    assert record["observation_statistics"]["controller"] == "mixed-team"
    # The last point of the curve is the file's play of the training seeds.
    last = json.loads((written[0].parent / "curve.json").read_text())["points"][-1]
    player = LockstepPlayer({MIXED: team.actor(MIXED)}, "continuous", sampled=False)
    played = player.play(MIXED, evaluation_seeds(MIXED))
    player.close()
    assert curve_point(played, 0.0, steps=400, bot_steps=1200)["mean"] == last["mean"]


@pytest.mark.slow
def test_a_recipe_that_prefers_continuous_actions_trains_and_exports_them(tmp_path):
    """IPPO on the steering robot's Rendezvous-v0 in continuous actions (its two and the
    two message values): the file is continuous, and the curve's last point is its play."""
    from bbbench.evaluation.episodes import LockstepPlayer
    from bbbench.training.logs import curve_point
    from bbbench.training.seeds import evaluation_seeds

    task = "bbbench/Rendezvous-v0"
    text = SMALL.replace(TASK, task).replace(
        "lr: 0.001", "lr: 0.001\n    prefer_continuous_actions: true"
    )
    out = tmp_path / "policy.onnx"
    argv = ["train", task, "--algo", "ippo", "--recipe", small_recipe(tmp_path, text)]
    assert main([*argv, "--out", str(out), *TRAIN]) == 0
    policy = load_policy(out)
    assert policy.action_mode == "continuous"
    assert json.loads((tmp_path / "train.json").read_text())["action_mode"] == "continuous"
    last = json.loads((tmp_path / "curve.json").read_text())["points"][-1]
    player = LockstepPlayer({task: policy.actor(task)}, "continuous", sampled=False)
    played = player.play(task, evaluation_seeds(task))
    player.close()
    assert curve_point(played, 0.0, steps=400, bot_steps=1600)["mean"] == last["mean"]


@pytest.mark.slow
def test_ippo_trains_exports_its_last_point_and_each_seed_is_its_own_runs_bytes(tmp_path):
    """A seed trained alone (its worlds in two processes) and the same seed among --seeds
    (in one), each in a fresh process, write the same bytes; another seed writes other
    bytes. The file written is the ONNX policy of the curve's last point, with its
    contract, and scores as the results document says."""
    plan = small_recipe(tmp_path)
    alone = tmp_path / "alone" / "policy.onnx"
    alone.parent.mkdir()
    argv = ["--recipe", plan, "--out", str(alone), "--workers", "2", *TRAIN]
    bbbench_cli("train", TASK, "--algo", "ippo", *argv)
    runs = tmp_path / "runs" / "policy.onnx"
    runs.parent.mkdir()
    argv = ["train", TASK, "--algo", "ippo", "--recipe", plan, "--seeds", "0,1", "--out", str(runs)]
    assert main([*argv, *TRAIN]) == 0

    seed0, seed1 = (runs.parent / f"policy-s{seed}" for seed in (0, 1))
    for name in ("policy.onnx", "results.json"):
        assert (seed0 / name).read_bytes() == (alone.parent / name).read_bytes(), name
    assert untimed(seed0 / "curve.json") == untimed(alone.parent / "curve.json")
    assert (seed1 / "policy.onnx").read_bytes() != alone.read_bytes()

    policy = load_policy(alone)
    assert policy.algorithm == "IPPO"
    record = json.loads((alone.parent / "train.json").read_text())
    curve = json.loads((alone.parent / "curve.json").read_text())["points"]
    assert [point["steps"] for point in curve] == [200, 400]
    assert record["checkpoint_rule"] == "last"
    assert record["observation_statistics"]["controller"] == classical_controller(TASK)
    assert record["observation_statistics"]["presence_bits"] == "unscaled"
    assert record["trainings_beside"]["samples"] >= 2  # counted at its start and its end
    assert record["kept"] == curve[-1]
    assert record["workers"] == 2
    assert json.loads((seed0 / "train.json").read_text())["workers"] == 1
    assert record["bot_steps"] == 400 * 3
    assert record["recipe"]["trainer"] == "BenchMARL"
    assert policy.contract.task == TASK
    # World steps, the board's unit: the contract, the record and the run agree.
    assert policy.contract.training_steps == record["kept"]["steps"] == record["steps"] == 400
    assert policy.contract.training_seed == 0

    # The file scores as train's results document says.
    scored = tmp_path / "scored.json"
    assert (
        main(
            [
                "eval",
                str(alone),
                "--task",
                TASK,
                "--episodes",
                "2",
                "--workers",
                "1",
                "--json",
                str(scored),
            ]
        )
        == 0
    )
    (scored_task,) = json.loads(scored.read_text())["tasks"]
    (trained_task,) = json.loads((alone.parent / "results.json").read_text())["tasks"]
    assert scored_task == trained_task


def test_the_normalizer_is_measured_on_standing_bots_and_repeats_from_its_seed():
    """The classical controller's play (a fifth of its actions random): the pitch spreads
    over hundredths of a radian there, not over the tenths of bots falling at random."""
    from bbbench.training.benchmarl.train import observation_statistics

    (group,) = statistics = observation_statistics("bbbench/MultiBalance-v1", {}, 0, "discrete")
    again = observation_statistics("bbbench/MultiBalance-v1", {}, 0, "discrete")
    assert group == "bot"  # the batched env's one group
    mean, std = statistics[group]
    assert mean.tobytes() == again[group][0].tobytes()
    assert std.tobytes() == again[group][1].tobytes()
    assert mean.shape == std.shape == (17,)
    assert std[0] < 0.1  # pitch, rad
    assert (std > 0).all()


@pytest.mark.parametrize(
    ("task_id", "mode"),
    [
        ("bbbench/Rendezvous-v0", "discrete"),
        ("bbbench/BeamCarry-v0", "discrete"),
        ("bbbench/MixedBeamCarry-v0", "continuous"),
    ],
)
def test_the_normalizer_leaves_each_slots_presence_bit_as_it_is(task_id, mode):
    """The neighbour encoder multiplies a slot by its presence bit: standardized, the bit
    would not read 0 or 1 (Rendezvous-v0's nearest sender, present in every row the
    controller's play gives, would read 0 and be hidden)."""
    from bbbench.envs.worlds import agent_groups
    from bbbench.training.benchmarl.train import observation_statistics

    task = bbbench.spec(task_id)
    scenario = task.scenario_class(task)
    statistics = observation_statistics(task_id, {}, 0, mode)
    for group, bots in agent_groups(task).items():
        mean, std = statistics[group]
        flags = list(scenario.bot_slots(bots[0]).presence_columns())
        assert flags  # every slot of these tasks has its bit
        assert (mean[flags] == 0.0).all()
        assert (std[flags] == 1.0).all()
    if not task.mixed:  # one layout: the bits by name
        names = agent_layout(task_id)
        assert {names[i].split("_")[-1] for i in scenario.slots().presence_columns()} == {"present"}


def test_the_steering_robot_normalizer_is_measured_under_its_own_controller():
    """On Swap-v0 the statistics come from `steer-avoid`: PD's nine actions are read by
    the steering robot as other ones (index 3 x forward + turn), its bots fall, and the
    pitch then spreads over 0.30 rad (measured), as under random play."""
    from bbbench.training.benchmarl.train import observation_statistics

    _, std = observation_statistics("bbbench/Swap-v0", {}, 0, "discrete")["bot"]
    assert std[0] < 0.15  # pitch, rad: 0.10 under steer-avoid


@pytest.mark.slow
def test_a_training_command_ends_without_warnings_of_leaked_semaphores(tmp_path):
    # `bbbench` leaves by os._exit: TorchRL's and tqdm's multiprocessing locks must be
    # gone by then, or the resource tracker warns of them.
    out = tmp_path / "policy.onnx"
    argv = [
        "train",
        "bbbench/MultiBalance-v1",
        "--algo",
        "ippo",
        "--steps",
        "10",
        "--out",
        str(out),
    ]
    done = subprocess.run(
        [sys.executable, "-m", "bbbench", *argv, "--eval-episodes", "1"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert "leaked" not in done.stderr, done.stderr
    assert out.exists()


def test_the_muted_runs_recipe_is_mappos_shipped_one_with_the_messages_muted():
    """The campaign's run with the messages muted changes one thing against MAPPO's
    shipped Rendezvous-v0 recipe (scripts/board_runs.py, `MUTED`)."""
    from bbbench.training.benchmarl.recipes import marl_recipe

    root = Path(__file__).resolve().parents[1]
    muted = load_script("board_runs").MUTED
    shipped = marl_recipe("mappo", "bbbench/Rendezvous-v0").record()
    changed = marl_recipe("mappo", "bbbench/Rendezvous-v0", root / muted["recipe"]).record()
    assert changed.pop("task") == {**shipped.pop("task"), "mute_messages": True}
    assert changed == shipped


def test_the_continuous_runs_recipe_is_ippos_shipped_one_in_continuous_actions():
    """The campaign's IPPO in continuous actions changes one thing against IPPO's shipped
    Rendezvous-v0 recipe (scripts/board_runs.py, `CONTINUOUS`)."""
    from bbbench.training.benchmarl.recipes import marl_recipe

    root = Path(__file__).resolve().parents[1]
    continuous = load_script("board_runs").CONTINUOUS
    shipped = marl_recipe("ippo", "bbbench/Rendezvous-v0")
    changed = marl_recipe("ippo", "bbbench/Rendezvous-v0", root / continuous["recipe"])
    assert (shipped.action_mode, changed.action_mode) == ("discrete", "continuous")
    experiment = dict(changed.record()["experiment"])
    assert experiment.pop("prefer_continuous_actions") is True
    assert {**changed.record(), "experiment": experiment} == shipped.record()

"""The records docs/tasks.md prints its calibrations from. The shared reward's calibration,
made again on validation seeds (scripts/calibrate_reward.py): the record is of the
candidates as declared, on the validation seeds; its figures follow from its own returns;
its pick follows the rule; and the shipped reward's returns are what the real env pays.
The two robots on the same ground (scripts/two_robots.py): each robot's episodes on its
own tasks are the board's, and on the other's ground what it plays. The team tasks'
calibration (scripts/calibrate_teams.py): on the validation seeds, its verdicts follow
from its episodes, and an episode replays."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

import bbbench
from bbbench.evaluation.harness import play_tasks
from bbbench.policies import load_policy
from bbbench.portable import total
from bbbench.tasks.spec import VALIDATION_SEEDS
from conftest import load_script

calibrate = load_script("calibrate_reward")


def _read(path: Path, script: str) -> dict:
    assert path.exists(), f"{path.name}: run python scripts/{script}.py --evaluate"
    return json.loads(path.read_text())


@pytest.fixture(scope="module")
def record() -> dict:
    return _read(calibrate.RECORD, "calibrate_reward")


def _shipped(record: dict) -> dict:
    return next(row for row in record["candidates"] if row["label"] == calibrate.SHIPPED_LABEL)


def test_the_record_is_the_declared_candidates_on_the_validation_seeds(record):
    assert record["split"] == "validation"
    assert record["seeds"] == {"first": VALIDATION_SEEDS[0], "count": len(VALIDATION_SEEDS)}
    assert record["tasks"] == list(calibrate.TASKS)
    assert [row["label"] for row in record["candidates"]] == list(calibrate.CANDIDATES)
    for row, reward in zip(record["candidates"], calibrate.CANDIDATES.values(), strict=True):
        assert row["weights"] == calibrate.weights(reward)
    # the shipped shape is the suite's reward, on every task the record covers
    for task_id in calibrate.TASKS:
        assert bbbench.spec(task_id).reward == calibrate.SHIPPED


def test_the_normalized_figures_follow_from_the_records_returns(record):
    for row in record["candidates"]:
        best_step = calibrate.CANDIDATES[row["label"]].max_step
        for task_id, task in row["tasks"].items():
            best = best_step * bbbench.spec(task_id).max_episode_steps
            means = task["mean_return"]
            for name in ("stand", "pd"):
                expected = (means[name] - means["random"]) / (best - means["random"])
                assert task[name] == expected, (row["label"], task_id, name)
    for task_id, task in _shipped(record)["tasks"].items():
        spec = bbbench.spec(task_id)
        bots = spec.group.n_bots if spec.multi_agent else 1
        for name, returns in task["returns"].items():
            assert len(returns) == len(VALIDATION_SEEDS) * bots  # every bot-episode
            assert task["mean_return"][name] == total(returns) / len(returns)


def test_the_pick_follows_the_rule_and_the_rule_can_refuse(record):
    assert record["picked"] == calibrate.pick(record["candidates"])
    assert record["holds"] == (record["picked"] == calibrate.SHIPPED_LABEL)
    # the rule reads the figures: a shipped shape whose stand passes 0.4 on one task is out
    rows = copy.deepcopy(record["candidates"])
    _shipped({"candidates": rows})["tasks"]["bbbench/Bumps-v2"]["stand"] = 0.41
    assert calibrate.pick(rows) != calibrate.SHIPPED_LABEL
    # and a shape without a tail never passes, whatever its figures
    no_tail = next(row for row in rows if row["label"] == "share 0.10, no tail")
    assert not calibrate.admitted(no_tail)


@pytest.mark.parametrize(
    ("task_id", "policy"), [("bbbench/VelocityTracking-v1", "stand"), ("bbbench/Bumps-v2", "pd")]
)
def test_the_shipped_rewards_returns_are_what_the_env_pays(record, task_id, policy):
    seeds = bbbench.spec(task_id).seeds("validation")[:3]
    played = play_tasks(load_policy(policy), [bbbench.spec(task_id)], workers=1, seeds=[seeds])
    paid = [episode.episode_return for episode in played.episodes[0]]
    stored = _shipped(record)["tasks"][task_id]["returns"][policy][:3]
    assert paid == stored  # bit for bit: the steps summed as the env sums them


# -- the two robots on the same ground (scripts/two_robots.py) ------------------------

two_robots = load_script("two_robots")
board_tables = load_script("board_tables")


@pytest.fixture(scope="module")
def robots_record() -> dict:
    return _read(two_robots.RECORD, "two_robots")


def test_each_robot_on_its_own_tasks_is_the_boards_controller(robots_record):
    """Where the robot is the task's own, the record's episodes are the board's, bit for
    bit: the same controller, ground, seeds and targets."""
    assert list(robots_record["tasks"]) == list(two_robots.TASKS)
    for task_id, by_robot in robots_record["tasks"].items():
        assert list(by_robot) == list(two_robots.ROBOTS)
        own = bbbench.spec(task_id).robot
        slug = "legged" if own == "wheel-legged" else "pd"
        recorded = [episode["return"] for episode in by_robot[own]]
        board = board_tables.controller(slug, task_id)["episodes"]
        assert recorded == [episode["return"] for episode in board], task_id


def test_a_robot_on_the_other_robots_ground_plays_the_recorded_episodes(robots_record):
    seeds = bbbench.spec("bbbench/LeggedBumps-v0").eval_seeds[:2]
    played = two_robots.play("bbbench/LeggedBumps-v0", "two-wheel", seeds)
    assert played == robots_record["tasks"]["bbbench/LeggedBumps-v0"]["two-wheel"][:2]


# -- the team tasks (scripts/calibrate_teams.py --evaluate) ---------------------------

teams = load_script("calibrate_teams")


@pytest.fixture(scope="module")
def teams_record() -> dict:
    return _read(teams.RECORD, "calibrate_teams")


def test_the_team_calibration_is_the_suites_tasks_on_the_validation_seeds(teams_record):
    assert teams_record["split"] == "validation"
    assert teams_record["seeds"] == {"first": VALIDATION_SEEDS[0], "count": len(VALIDATION_SEEDS)}
    assert list(teams_record["tasks"]) == list(teams.TEAM_TASKS)
    for task in teams_record["tasks"].values():
        assert list(task["policies"]) == list(teams.POLICIES)
        for row in task["policies"].values():
            assert len(row["returns"]) == len(row["lengths"]) == len(VALIDATION_SEEDS)


def test_the_team_calibrations_verdicts_follow_from_its_episodes(teams_record):
    from bbbench.evaluation import stats

    for name, task in teams_record["tasks"].items():
        rows = task["policies"]
        zero = float(np.mean(rows["random"]["returns"]))
        best = bbbench.spec(name).max_return
        normalized = {p: (np.array(r["returns"]) - zero) / (best - zero) for p, r in rows.items()}
        for policy, row in rows.items():
            assert row["normalized"] == float(normalized[policy].mean())
            assert row["finished"] == float(np.mean([n == 1500 for n in row["lengths"]]))
        point, interval = stats.probability_of_improvement(
            [normalized["team"]], [normalized["naive"]]
        )
        assert task["p_team_over_naive"] == [point, list(interval)]
        team = rows["team"]
        meets = (
            interval[0] > 0.5
            and (team["normalized"] <= 0.7 or team["finished"] <= 0.6)
            and rows["random"]["finished"] == 0
        )
        assert task["meets"] == meets, name
    assert teams_record["holds"] == all(task["meets"] for task in teams_record["tasks"].values())


def test_a_team_calibration_episode_is_what_the_controller_plays(teams_record):
    seed = VALIDATION_SEEDS[0]
    length, team_return = teams.play(("bbbench/Convoy-v0", "team", seed))
    row = teams_record["tasks"]["bbbench/Convoy-v0"]["policies"]["team"]
    assert (length, team_return) == (row["lengths"][0], row["returns"][0])


# -- the mixed team (scripts/calibrate_mixed.py --evaluate) ------------------------------

mixed = load_script("calibrate_mixed")


@pytest.fixture(scope="module")
def mixed_record() -> dict:
    return _read(mixed.RECORD, "calibrate_mixed")


def test_the_mixed_calibration_is_both_mixed_tasks_on_the_validation_seeds(mixed_record):
    assert mixed_record["split"] == "validation"
    assert mixed_record["seeds"] == {"first": VALIDATION_SEEDS[0], "count": len(VALIDATION_SEEDS)}
    assert list(mixed_record["tasks"]) == list(mixed.MIXED_TASKS)
    assert mixed_record["roles"] == {"random": "random", "naive": "per-bot", "team": "mixed-team"}
    for name, task in mixed_record["tasks"].items():
        assert bbbench.spec(name).mixed
        assert list(task["policies"]) == list(teams.POLICIES)
        for row in task["policies"].values():
            assert len(row["returns"]) == len(row["lengths"]) == len(VALIDATION_SEEDS)
    assert mixed_record["holds"]


def test_a_mixed_calibration_episode_is_what_the_builtin_plays(mixed_record):
    task_id = "bbbench/MixedBeamCarryBumps-v0"
    for role in ("team", "naive"):
        length, team_return = mixed.play((task_id, role, VALIDATION_SEEDS[1]))
        row = mixed_record["tasks"][task_id]["policies"][role]
        assert (length, team_return) == (row["lengths"][1], row["returns"][1])


pilot = load_script("pilot_rendezvous")


@pytest.mark.parametrize("tell", ["one-hot", "direct"])
def test_a_rendezvous_pilot_tells_every_bot_the_goal_of_fewer_landmarks(monkeypatch, tell):
    """docs/notebook.md's pilots: every bot's row holds the scout's one-hot (of two
    landmarks here); `direct` also gives every landmark's slot the goal's own values."""
    from bbbench.tasks.suite import agent_layout

    pilot.apply(pilot.parse(["--tell", tell, "--landmarks", "2"]), monkeypatch.setattr)
    env = bbbench.make_parallel(pilot.TASK)
    observations, _ = env.reset(seed=3)
    first, told = pilot.places()
    assert "landmark2_distance" not in agent_layout(pilot.TASK)
    rows = np.stack(list(observations.values()))
    one_hot = np.zeros(2)
    one_hot[env._scenario.goal] = 1.0
    assert (rows[:, told : told + 2] == one_hot).all()  # every bot's the scout's
    same = (rows[:, first : first + 3] == rows[:, first + 3 : first + 6]).all()
    assert same == (tell == "direct")
    env.close()


@pytest.mark.parametrize("muted", [False, True])
def test_a_beacon_hears_the_scout_alone_while_it_speaks(monkeypatch, muted):
    """`--beacon`: the scout's landmark values are the goal's, the others' zeros; after a
    step in which the scout says (1, 1) and the others nothing, each bot within range
    hears one sender, the scout, and, muted, none."""
    from bbbench.tasks.channel import code_of, sender_slots
    from bbbench.tasks.suite import agent_layout

    pilot.apply(pilot.parse(["--landmarks", "2", "--beacon"]), monkeypatch.setattr)
    env = bbbench.make_parallel(pilot.TASK, mute_messages=muted)
    env.reset(seed=3)
    scenario = env._scenario
    scout = env.possible_agents[scenario.scout]
    speak, hush = code_of((1.0, 1.0)), code_of((0.0, 0.0))
    observations, *_ = env.step({bot: speak if bot == scout else hush for bot in env.agents})
    first, _ = pilot.places()
    slots = sender_slots(agent_layout(pilot.TASK))
    heard = 0
    for bot, row in observations.items():
        if bot == scout:
            goal = row[first + 3 * scenario.goal : first + 3 * scenario.goal + 3]
            assert (row[first : first + 6] == np.tile(goal, 2)).all()
            assert goal[0] > 0.0
        else:
            assert not row[first : first + 6].any()
        present = [slot for slot in slots if row[slot.present] == 1.0]
        assert all(not row[slot.right : slot.present + 1].any() for slot in slots
                   if slot not in present)  # fmt: skip
        if present:
            (slot,) = present  # one sender heard: the scout
            assert bot != scout
            assert list(row[list(slot.messages)]) == [1.0, 1.0]
        heard += len(present)
    where = [state.position for state in env._states]
    x, y = where[scenario.scout][0], where[scenario.scout][1]
    reach = scenario.channel.range**2
    near = sum((p[0] - x) ** 2 + (p[1] - y) ** 2 <= reach for p in where) - 1
    assert near > 0
    assert heard == (0 if muted else near)  # the bots within the channel's range of it
    # The variant's controller: the scout says (1, 1), the others nothing.
    from bbbench.policies import load_policy

    actor = load_policy("rendezvous").actor(pilot.TASK)
    codes = [int(action) % env.task.channel.codes for action in actor(
        np.stack(list(observations.values())), None)]  # fmt: skip
    assert codes == [speak if bot == scout else hush for bot in observations]
    env.close()


def test_the_arrival_profile_tells_a_team_at_the_goal_from_one_in_the_middle(monkeypatch):
    """`--arrival`: the controller, told the goal, drives towards it at once and ends its
    holds nearer it than the other landmark (a team in the landmarks' middle would end
    as near both)."""
    pilot.apply(pilot.parse(["--tell", "one-hot", "--landmarks", "2"]), monkeypatch.setattr)
    seeds = pilot.evaluation_seeds(pilot.TASK)[:2]
    told = pilot.arrival("rendezvous", seeds, width=100)
    assert [row[0] for row in told] == [100 * k for k in range(len(told))]
    late = [row for row in told if row[0] >= 300]
    assert late
    assert all(goal < 1.5 < 2.5 < other for _, _, goal, other, _ in late)
    assert told[1][1] > 0.5  # it drives towards the goal as soon as it is told


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["--own-share", "2"], "--own-share 2.0: expected a weight from 0 to 1"),
        (["--hold", "6,3"], "--hold '6,3': expected 0 < LOW <= HIGH"),
        (["--seeds", "0,one"], "--seeds '0,one': expected whole numbers, e.g. 0,1,2"),
        (["--arrival"], "--arrival plays a policy: give it with --play, e.g. --play policy.onnx"),
        (["--beacon", "--tell", "direct"], "a beacon tells the scout alone"),
    ],
)
def test_a_pilots_bad_variant_is_refused_in_one_line(capsys, argv, expected):
    with pytest.raises(SystemExit) as stop:
        pilot.parse(argv)
    assert stop.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1].endswith(expected)


def test_the_entities_pilots_actor_reads_the_landmarks_as_a_set_and_plays_exported(monkeypatch):
    """`--entities`: the actor's landmark encoder sees each landmark through one shared
    layer, so that, but for each landmark's own code, swapping two landmarks (their values
    and told bits) changes nothing in its features; exported, bbbench's interpreter plays
    the actor as torch does."""
    import torch

    import bbbench.marl.models
    from bbbench.marl.models import NeighbourEncoderConfig
    from bbbench.policies.onnx.export import onnx_bytes
    from bbbench.policies.onnx.policy import OnnxPolicy
    from bbbench.policies.onnx.reader import parse_onnx

    variant = pilot.parse(["--tell", "one-hot", "--landmarks", "2", "--entities"])
    pilot.apply(variant, monkeypatch.setattr)
    config = NeighbourEncoderConfig.for_task(pilot.TASK)
    torch.manual_seed(0)
    net = bbbench.marl.models.neighbour_encoder(
        config.own, config.slots, config.slot_width, 243, config.presence, 32, (64, 64), "mean"
    )
    env = bbbench.make_parallel(pilot.TASK)
    observations, _ = env.reset(seed=3)
    env.close()
    rows = np.stack(list(observations.values())).astype(np.float32)
    # Exported as trained (each landmark with its code), the interpreter plays it as torch.
    with torch.no_grad():
        scores = net(torch.from_numpy(rows)).numpy()
    policy = OnnxPolicy(parse_onnx(onnx_bytes(net, pilot.TASK, algorithm="IPPO"), "p", "p.onnx"))
    assert list(policy.actor(pilot.TASK)(rows)) == list(scores.argmax(axis=1))
    first, told = pilot.places()
    swapped = rows.copy()
    swapped[:, first : first + 6] = np.roll(rows[:, first : first + 6], 3, axis=1)
    swapped[:, told : told + 2] = rows[:, [told + 1, told]]
    with torch.no_grad():
        pooled = net.senders(torch.from_numpy(rows))
        coded = net.landmarks(torch.from_numpy(rows), pooled)
        assert not torch.allclose(coded, net.landmarks(torch.from_numpy(swapped), pooled))
        net.code.zero_()
        same = [net.landmarks(torch.from_numpy(r), pooled).numpy() for r in (rows, swapped)]
    np.testing.assert_allclose(same[0], same[1], atol=1e-5)


def test_an_in_range_pilot_tells_the_bots_within_the_channels_range_of_the_scout(monkeypatch):
    """`--tell in-range`: the scout's one-hot in the rows of the scout and of the bots
    within the channel's range of it, zeros in the others'."""
    pilot.apply(pilot.parse(["--tell", "in-range", "--landmarks", "2"]), monkeypatch.setattr)
    _, told = pilot.places()
    env = bbbench.make_parallel(pilot.TASK)
    observations, _ = env.reset(seed=3)  # two bots out of the scout's range
    scenario, states = env._scenario, env._states
    scout, reach = states[scenario.scout].position, scenario.channel.range
    assert len(states) - 1 <= scenario.channel.slots  # so range alone decides who hears
    for row, state in zip(observations.values(), states, strict=True):
        where = state.position
        near = (where[0] - scout[0]) ** 2 + (where[1] - scout[1]) ** 2 <= reach**2
        assert row[told + scenario.goal] == float(near)
        assert row[told + 1 - scenario.goal] == 0.0
    assert sorted(row[told + scenario.goal] for row in observations.values()) == [0, 0, 1, 1]
    env.close()


@pytest.mark.parametrize("wired", [True, False])
def test_a_wired_scout_is_heard_saying_the_goal_at_the_first_step(monkeypatch, wired):
    """`--wired`: the scout's message is the controller's word for the goal, whatever it
    sent (at reset, nothing); the bots within the channel's range hear it."""
    from bbbench.tasks.suite import agent_layout

    variant = pilot.parse(["--landmarks", "2", *(["--wired"] if wired else [])])
    pilot.apply(variant, monkeypatch.setattr)
    env = bbbench.make_parallel(pilot.TASK)
    observations, _ = env.reset(seed=3)
    names = list(agent_layout(pilot.TASK))
    word = pilot.controller.TOLD[env._scenario.goal]
    heard = [
        tuple(row[names.index(f"sender{k}_message0") :][:2]) == word
        for row in observations.values()
        for k in (1, 2, 3)
    ]
    assert any(heard) == wired
    env.close()


def test_a_hushed_variant_hears_the_scout_alone(monkeypatch):
    """`--hush`: after a step in which every bot says (1, 1), a bot hears it from the
    scout alone; without it, from every sender in range."""
    from bbbench.tasks.suite import agent_layout

    saying = {}
    for hush in (False, True):
        variant = pilot.parse(["--landmarks", "2", *(["--hush"] if hush else [])])
        with monkeypatch.context() as patch:
            pilot.apply(variant, patch.setattr)
            names = list(agent_layout(pilot.TASK))
            env = bbbench.make_parallel(pilot.TASK)
            env.reset(seed=3)
            said = env.task.channel.codes - 1  # (1, 1), with the robot's first action
            observations, *_ = env.step({bot: said for bot in env.agents})
            scout = env.possible_agents[env._scenario.scout]
            saying[hush] = {
                bot: [
                    (
                        row[names.index(f"sender{k}_message0")],
                        row[names.index(f"sender{k}_message1")],
                    )
                    == (1.0, 1.0)
                    for k in (1, 2, 3)
                ]
                for bot, row in observations.items()
            }
            env.close()
    heard = {hush: sum(sum(said) for said in bots.values()) for hush, bots in saying.items()}
    assert heard[False] > heard[True] > 0
    assert sum(saying[True][scout]) == 0  # the scout hears no one: the others are silent
    assert all(sum(said) <= 1 for said in saying[True].values())  # the scout alone

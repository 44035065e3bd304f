"""The message channel (`bbbench.tasks.channel`) and the task that needs it, Rendezvous
(`bbbench.tasks.scenarios.rendezvous`): its spaces, its one-step delay, its bounds, and
that the classical controller's score rests on what its messages carry."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from gymnasium import spaces
from pettingzoo.test import parallel_api_test, parallel_seed_test

import bbbench
from bbbench.evaluation.harness import play_tasks
from bbbench.policies import load_policy
from bbbench.policies.controllers.rendezvous import NOTHING, RELAYED, TOLD, heard
from bbbench.robots.steering import DISCRETE_ACTIONS
from bbbench.tasks.channel import LEVELS, Channel, code_of, sender_slots
from bbbench.tasks.suite import agent_layout, spec

RENDEZVOUS = "bbbench/Rendezvous-v0"
STILL = DISCRETE_ACTIONS.index((0.0, 0.0))  # the steering robot's "change nothing"


def _slot_values(layout: tuple[str, ...], observation: np.ndarray, k: int) -> dict[str, float]:
    prefix = f"sender{k}_"
    return {
        name[len(prefix) :]: float(value)
        for name, value in zip(layout, observation, strict=True)
        if name.startswith(prefix)
    }


def test_the_action_grows_by_the_message_values_in_both_modes():
    env = bbbench.make_parallel(RENDEZVOUS)
    assert env.action_space("bot_0") == spaces.Discrete(27 * 9)
    env = bbbench.make_parallel(RENDEZVOUS, action_mode="continuous", message_width=3)
    space = env.action_space("bot_0")
    assert space.shape == (5,)
    assert space.low.tolist() == [-1.0] * 5
    assert space.high.tolist() == [1.0] * 5
    names = agent_layout(RENDEZVOUS)
    assert env.observation_space("bot_0").shape == (len(names) + 3,)  # a value more per slot


def test_every_discrete_message_code_round_trips():
    channel = Channel(width=3)
    split = channel.splitter(spaces.Discrete(27))
    for code in range(channel.codes):
        robot, message = split(5 * channel.codes + code)
        assert robot == 5
        assert set(message) <= set(LEVELS)
        assert code_of(message) == code


def test_a_message_arrives_with_the_observation_the_step_returns_and_not_before():
    env = bbbench.make_parallel(RENDEZVOUS, n_bots=2, comm_range=20.0)
    layout = agent_layout(RENDEZVOUS)
    observations, _ = env.reset(seed=3)
    heard_at_reset = _slot_values(layout, observations["bot_1"], 1)
    assert heard_at_reset["present"] == 1.0
    assert (heard_at_reset["message0"], heard_at_reset["message1"]) == (0.0, 0.0)
    said = code_of((1.0, -1.0))
    actions = {"bot_0": STILL * 9 + said, "bot_1": STILL * 9 + code_of((0.0, 0.0))}
    observations, *_ = env.step(actions)
    slot = _slot_values(layout, observations["bot_1"], 1)
    assert (slot["message0"], slot["message1"]) == (1.0, -1.0)
    # bot_1 said nothing; bot_0 hears that, where bot_1 stands.
    back = _slot_values(layout, observations["bot_0"], 1)
    assert (back["message0"], back["message1"]) == (0.0, 0.0)
    assert np.hypot(back["right"], back["forward"]) == pytest.approx(
        np.hypot(slot["right"], slot["forward"]), rel=1e-5
    )
    observations, *_ = env.step({agent: STILL * 9 + code_of((0.0, 0.0)) for agent in env.agents})
    slot = _slot_values(layout, observations["bot_1"], 1)
    assert (slot["message0"], slot["message1"]) == (0.0, 0.0)  # the next step's message
    env.close()


def test_muted_messages_read_zero_but_the_sender_is_still_there():
    env = bbbench.make_parallel(RENDEZVOUS, n_bots=2, comm_range=20.0, mute_messages=True)
    layout = agent_layout(RENDEZVOUS)
    env.reset(seed=3)
    observations, *_ = env.step({agent: STILL * 9 + code_of((1.0, 1.0)) for agent in env.agents})
    slot = _slot_values(layout, observations["bot_1"], 1)
    assert (slot["message0"], slot["message1"], slot["present"]) == (0.0, 0.0, 1.0)
    assert abs(slot["right"]) + abs(slot["forward"]) > 1.0
    env.close()


def test_sender_slots_find_each_slots_columns_in_the_row():
    """`sender_slots`: each slot's place, message and presence columns, nearest first,
    whatever the width and count; none in a row without a channel."""
    channel = Channel(width=3, slots=2)
    names = ("pitch", *(field.name for field in channel.layout()), "after")
    slots = sender_slots(names)
    assert [names[slot.right] for slot in slots] == ["sender1_right", "sender2_right"]
    assert [[names[c] for c in slot.messages] for slot in slots][1] == [
        "sender2_message0", "sender2_message1", "sender2_message2"
    ]  # fmt: skip
    assert [slot.present - slot.right for slot in slots] == [5, 5]
    assert names[slots[1].present] == "sender2_present"
    assert sender_slots(agent_layout("bbbench/Swap-v0")) == []
    assert len(sender_slots(agent_layout(RENDEZVOUS))) == spec(RENDEZVOUS).channel.slots


def test_a_sender_beyond_the_range_is_not_heard():
    env = bbbench.make_parallel(RENDEZVOUS, n_bots=2, comm_range=0.5)
    layout = agent_layout(RENDEZVOUS)
    observations, _ = env.reset(seed=3)
    for observation in observations.values():
        assert set(_slot_values(layout, observation, 1).values()) == {0.0}
    env.close()


def test_only_the_scout_is_told_the_goal_and_every_bot_earns_the_teams_reward():
    env = bbbench.make_parallel(RENDEZVOUS)
    layout = list(agent_layout(RENDEZVOUS))
    told = layout.index("goal_is_landmark0")
    scouts = set()
    for seed in range(6):
        observations, _ = env.reset(seed=seed)
        scenario = env.unwrapped.scene.scenario
        one_hots = {agent: obs[told : told + 4] for agent, obs in observations.items()}
        knowing = [agent for agent, hot in one_hots.items() if hot.any()]
        assert knowing == [f"bot_{scenario.scout}"]
        assert one_hots[knowing[0]].argmax() == scenario.goal
        scouts.add(scenario.scout)
        _, rewards, *_ = env.step(dict.fromkeys(env.agents, STILL * 9))
        assert len(set(rewards.values())) == 1
    assert len(scouts) > 1
    env.close()


@pytest.mark.parametrize(
    ("keyword", "value", "words"),
    [
        ("message_width", 0, "message_width must be a whole number from 1 to 4, got 0"),
        ("message_width", 2.5, "message_width must be a whole number from 1 to 4, got 2.5"),
        ("message_width", 9, "message_width must be a whole number from 1 to 4, got 9"),
        ("comm_range", 0.0, "comm_range must be a distance in (0, 20] m, got 0.0"),
        ("comm_range", 50, "comm_range must be a distance in (0, 20] m, got 50"),
        ("comm_range", "far", "comm_range must be a distance in (0, 20] m, got 'far'"),
        ("mute_messages", "yes", "mute_messages must be True or False, got 'yes'"),
    ],
)
def test_a_channel_option_out_of_bounds_is_one_clear_line(keyword, value, words):
    with pytest.raises(ValueError, match=keyword) as raised:
        bbbench.make_parallel(RENDEZVOUS, **{keyword: value})
    assert str(raised.value) == words


def test_a_task_without_a_channel_refuses_its_options():
    with pytest.raises(TypeError, match=r"unknown keyword argument\(s\) \['message_width'\]"):
        bbbench.make_parallel("bbbench/Swap-v0", message_width=2)


def test_actions_outside_the_grown_space_are_refused_with_what_was_expected():
    env = bbbench.make_parallel(RENDEZVOUS, n_bots=2)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"'bot_0'.*integer index 0\.\.242"):
        env.step({"bot_0": 243, "bot_1": 0})
    env = bbbench.make_parallel(RENDEZVOUS, n_bots=2, action_mode="continuous")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"message values \[2\.0, 0\.0\] are not in \[-1, 1\]"):
        env.step({"bot_0": np.array([0, 0, 2, 0], np.float32), "bot_1": np.zeros(4, np.float32)})
    with pytest.raises(ValueError, match=r"expected 4 values, the robot's 2 then 2 message"):
        env.step({"bot_0": np.zeros(3, np.float32), "bot_1": np.zeros(4, np.float32)})


def test_the_env_passes_pettingzoos_checks():
    parallel_api_test(bbbench.make_parallel(RENDEZVOUS), num_cycles=200)
    parallel_seed_test(lambda: bbbench.make_parallel(RENDEZVOUS))


def test_the_words_say_each_landmark_first_hand_or_relayed_and_zeros_say_nothing():
    assert [heard(words) for words in TOLD] == [(k, True) for k in range(4)]
    assert [heard(words) for words in RELAYED] == [(k, False) for k in range(4)]
    assert heard(NOTHING) is None
    assert heard((0.9, -0.7)) == (2, True)  # the nearest levels


def test_the_goal_moves_on_and_the_scout_is_told_each_time():
    env = bbbench.make_parallel(RENDEZVOUS, n_bots=2)
    layout = list(agent_layout(RENDEZVOUS))
    told = layout.index("goal_is_landmark0")
    observations, _ = env.reset(seed=11)
    scenario = env.unwrapped.scene.scenario
    schedule = scenario.schedule
    assert all(300 <= b[0] - a[0] <= 600 for a, b in itertools.pairwise(schedule))
    assert all(a[1] != b[1] for a, b in itertools.pairwise(schedule))
    scout = f"bot_{scenario.scout}"
    act = load_policy("rendezvous").actor(RENDEZVOUS)
    for step in range(1, schedule[1][0] + 2):
        agents = env.agents
        actions = act(np.stack([observations[agent] for agent in agents]), None)
        observations, *_ = env.step(dict(zip(agents, actions, strict=True)))
        expected = schedule[0][1] if step < schedule[1][0] else schedule[1][1]
        assert observations[scout][told : told + 4].argmax() == expected, step
    env.close()


def test_the_controller_scores_on_its_messages():
    """The channel carries the task: the controller with its messages muted drives no
    bot but the scout, and scores far below the same controller heard."""
    task = spec(RENDEZVOUS)
    seeds = [list(task.validation_seeds[:3])] * 2
    played = play_tasks(
        load_policy("rendezvous"), [task, task.with_channel(mute_messages=True)], seeds=seeds
    )
    heard_returns, muted_returns = (
        [episode.episode_return for episode in episodes] for episodes in played.episodes
    )
    assert min(heard_returns) > max(muted_returns) + 25.0


def test_a_policy_trained_with_the_messages_muted_hears_none_in_any_env():
    """`heard_mask`: the exported policy of a muted training multiplies every message
    value by 0, so that on the task as it is it plays as it trained."""
    import torch

    from bbbench.policies.onnx.export import onnx_bytes
    from bbbench.policies.onnx.policy import OnnxPolicy
    from bbbench.policies.onnx.reader import parse_onnx
    from bbbench.training.benchmarl.train import heard_mask

    layout = agent_layout(RENDEZVOUS)
    mask = heard_mask(RENDEZVOUS, {"mute_messages": True})
    assert [name for name, kept in zip(layout, mask, strict=True) if not kept] == [
        f"sender{k}_message{j}" for k in (1, 2, 3) for j in (0, 1)
    ]
    assert heard_mask(RENDEZVOUS, {"mute_messages": False}) is None
    torch.manual_seed(0)
    network = torch.nn.Linear(len(layout), 243)
    content = onnx_bytes(network, RENDEZVOUS, mask=mask)
    actor = OnnxPolicy(parse_onnx(content, "muted.onnx", "muted.onnx")).actor(RENDEZVOUS)
    observation = np.random.default_rng(0).uniform(-1, 1, (1, len(layout))).astype(np.float32)
    other = observation.copy()
    other[0, mask == 0] = -observation[0, mask == 0]
    assert np.array_equal(actor.program(observation), actor.program(other))
    other[0, 0] += 0.5  # a value it hears
    assert not np.array_equal(actor.program(observation), actor.program(other))

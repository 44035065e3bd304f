"""Teams of another size at test time (issue 67): the board's neighbour-encoder policies,
trained with 4 bots, play any number of bots, since each bot reads its K nearest
neighbours in fixed slots."""

from __future__ import annotations

from pathlib import Path

import pytest

import bbbench
from bbbench.evaluation.harness import play_tasks
from bbbench.evaluation.profile import profile, profile_document, stored_records
from bbbench.evaluation.sweep import variant
from bbbench.evaluation.team_sizes import TEAM_SIZES, TeamSizes, trained_size
from bbbench.policies import load_policy
from bbbench.tasks.tracks import TRACKS

BOARD = Path(__file__).resolve().parents[1] / "leaderboards" / "submissions"


@pytest.mark.parametrize(
    ("method", "task_id"),
    [
        ("ippo-multibalance-v1-3m", "bbbench/MultiBalance-v1"),
        ("mappo-swap-v0-3m", "bbbench/Swap-v0"),
    ],
)
def test_a_neighbour_encoder_policy_plays_every_team_size(method, task_id):
    policy = load_policy(BOARD / method / "runs" / "s0" / "policy.onnx")
    task = bbbench.spec(task_id)
    sizes = (2, 4, 6, 8)
    tasks = [variant(task, "n_bots", size) for size in sizes]
    played = play_tasks(policy, tasks, seeds=[task.eval_seeds[:1]] * len(sizes), workers=1)
    for size, (episode,) in zip(sizes, played.episodes, strict=True):
        assert episode.failure is None, (size, episode.failure)
        assert episode.length > 100, size  # it drives, not only its first step
    assert [t.group.n_bots for t in tasks] == list(sizes)


@pytest.mark.parametrize("size", [1, 9, 17])
def test_a_team_size_outside_the_tasks_range_is_one_clear_line(size):
    with pytest.raises(ValueError, match="n_bots must be") as raised:
        variant(bbbench.spec("bbbench/Swap-v0"), "n_bots", size)
    assert "\n" not in str(raised.value)


@pytest.mark.parametrize("sizes", [(2, 9), (1, 4)])
def test_a_team_size_profile_outside_the_tasks_range_is_one_line(sizes):
    with pytest.raises(ValueError, match=r"team-size profile on bbbench/Swap-v0: .*n_bots must"):
        TeamSizes(episodes=1, sizes=sizes).specs("bbbench/Swap-v0")


def test_the_board_profiles_team_sizes_on_the_tracks_that_declare_them():
    """MultiBalance-v1 and Swap-v0, the multi-bot tracks' profile tasks; not a team's
    track (a beam takes 2 to 4 bots) nor the single-bot ones."""
    sized = {name: track.profiled_on for name, track in TRACKS.items() if track.team_sizes}
    assert sized == {"multi": "bbbench/MultiBalance-v1", "steering-multi": "bbbench/Swap-v0"}
    for task_id in sized.values():
        specs = TEAM_SIZES.specs(task_id)
        assert [size for _, size, _ in specs] == [2, 4, 6, 8]
        assert [task.group.n_bots for _, _, task in specs] == [2, 4, 6, 8]
        assert len({task.fingerprint for _, _, task in specs}) == 4


def test_the_training_size_is_the_recipes_else_the_tasks_and_none_for_a_controller():
    trained = {"recipe": {"world_steps": 3_000_000, "tasks": ["bbbench/Swap-v0"]}}
    assert trained_size(trained, "bbbench/Swap-v0") == 4
    six = {"recipe": {"world_steps": 1000, "n_bots": 6}}
    assert trained_size(six, "bbbench/Swap-v0") == 6
    assert trained_size({"recipe": {"world_steps": 0}}, "bbbench/Swap-v0") is None
    # The size of the task it trained on, not the profile task's: a run of a 3-bot team
    # task profiled on a 4-bot task was trained with 3.
    beam = {"recipe": {"world_steps": 1000, "tasks": ["bbbench/BeamCarry-v0"]}}
    assert trained_size(beam, "bbbench/MultiBalance-v1") == 3


def test_a_team_size_profile_document_holds_every_episode_and_its_aggregates():
    """The document is the robustness profile's kind, one axis (n_bots), and can be
    computed again from its records."""
    protocol = TeamSizes(episodes=1, sizes=(2, 3))
    document = profile(load_policy("steer-avoid"), 1, protocol=protocol, task_id="bbbench/Swap-v0")
    (block,) = document["axes"]
    assert block["axis"] == "n_bots"
    assert block["unit"] == "bots in the world"
    assert [point["value"] for point in block["points"]] == [2, 3]
    assert document["protocol"]["axes"] == {"n_bots": [2, 3]}
    again = profile_document(
        document["policy"], "bbbench/Swap-v0", False, stored_records(document), protocol
    )
    assert again == document

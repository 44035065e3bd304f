"""The choices made again on validation seeds (scripts/choices.py): each record is of the
choice as declared, on the validation seeds, its pick follows the rule from its own
episodes, and its episodes are what the candidates play."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bbbench.evaluation.harness import play_tasks
from bbbench.tasks.spec import VALIDATION_SEEDS
from conftest import load_script

choices = load_script("choices")
RECORDS = {name: choices.record_path(name) for name in choices.CHOICES}


def _record(name: str) -> dict:
    path = RECORDS[name]
    assert path.exists(), f"{path.name}: run python scripts/choices.py --train/--evaluate {name}"
    return json.loads(path.read_text())


@pytest.mark.parametrize("name", sorted(RECORDS))
def test_a_record_is_its_choice_on_the_validation_seeds(name):
    record, choice = _record(name), choices.CHOICES[name]
    assert record["split"] == "validation"
    assert record["seeds"] == {"first": VALIDATION_SEEDS[0], "count": len(VALIDATION_SEEDS)}
    assert [row["label"] for row in record["candidates"]] == [c.label for c in choice.candidates]
    assert record["tasks"] == list(choice.tasks)
    assert record["shipped"] == choice.shipped
    assert (record["question"], record["rule"], record["was"]) == (
        choice.question,
        choice.rule,
        choice.was,
    )
    for row in record["candidates"]:
        assert list(row["tasks"]) == list(choice.tasks)
        assert all(len(task["returns"]) == len(VALIDATION_SEEDS) for task in row["tasks"].values())


@pytest.mark.parametrize("name", sorted(RECORDS))
def test_the_pick_follows_the_rule_from_the_records_own_episodes(name):
    record, choice = _record(name), choices.CHOICES[name]
    rows = record["candidates"]
    shipped = next(row for row in rows if row["label"] == choice.shipped)
    if choice.kind == "task":
        low, high = choices.BAND
        admitted = [
            r["label"]
            for r in rows
            if all(low <= t["finished"] <= high for t in r["tasks"].values())
        ]
        assert record["in_band"] == admitted
        assert record["holds"] == (choice.shipped in admitted)
        return
    best = max(rows, key=lambda row: row["score"])
    if best is not shipped:
        point, interval = choices.probability_of_improvement_of(best, shipped)
        assert [point, list(interval)] == best["p_over_shipped"]
        assert record["holds"] == (interval[0] <= 0.5)
    else:
        assert record["holds"]


def test_a_candidates_episodes_are_what_it_plays():
    """One candidate of a task's calibration, played again: the same returns, bit for bit."""
    record, choice = _record("pushrecovery-growth"), choices.CHOICES["pushrecovery-growth"]
    candidate = choice.candidates[2]
    policy, _ = choices.candidate_policy(choice, candidate)
    tasks = choices.candidate_tasks(choice, candidate)
    seeds = [task.seeds("validation")[:16] for task in tasks]
    played = play_tasks(policy, tasks, workers=1, seeds=seeds)
    returns = [episode.episode_return for episode in played.episodes[0]]
    stored = record["candidates"][2]["tasks"][choice.tasks[0]]["returns"][:16]
    assert np.array_equal(returns, stored)

"""A results document as text (`bbbench.evaluation.results.dumps`/`loads`): each task's
episodes as a table, one row per line, read back as the records they were; the form
before the tables (one object per episode) read as it is; a table that does not fit
its columns refused."""

from __future__ import annotations

import json

import pytest

from bbbench.evaluation import evaluate
from bbbench.evaluation.results import dumps, loads
from bbbench.policies import load_policy
from conftest import follows_results_schema

TEAM = "bbbench/BeamCarry-v0"  # its records carry a cause; a solo task's do not


@pytest.fixture(scope="module")
def document():
    """A team task's document, with a solo task's block before its own."""
    team = evaluate(load_policy("team"), [TEAM], episodes=3, workers=1).document
    solo = evaluate(load_policy("pd"), ["bbbench/FlatBalance-v1"], episodes=3, workers=1)
    return team | {"tasks": [*solo.document["tasks"], *team["tasks"]]}


def test_the_text_holds_a_table_per_task_and_reads_back_as_the_records(document):
    text = dumps(document)
    raw = json.loads(text)
    for block, written in zip(document["tasks"], raw["tasks"], strict=True):
        table = written["episodes"]
        assert table["columns"][:5] == ["seed", "return", "length", "falls", "success"]
        assert [row[0] for row in table["rows"]] == block["seeds"]
    assert "cause" in raw["tasks"][1]["episodes"]["columns"]
    assert "cause" not in raw["tasks"][0]["episodes"]["columns"]
    assert loads(text) == document
    assert dumps(loads(text)) == text
    follows_results_schema(raw)
    rows = [line for line in text.splitlines() if line.lstrip().startswith("[2")]
    assert len(rows) == 6  # one line per episode


def test_a_document_written_before_the_tables_is_read_as_it_is(document):
    before = json.dumps(document, indent=2)  # schema 2's text: one object per episode
    assert loads(before) == document


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda table: table["rows"][1].pop(), "expected rows of"),
        (lambda table: table.pop("columns"), "expected a table of columns and rows"),
        (lambda table: table.update(extra=1), "expected a table of columns and rows"),
    ],
)
def test_a_table_that_does_not_fit_its_columns_is_refused(document, change, message):
    raw = json.loads(dumps(document))
    change(raw["tasks"][0]["episodes"])
    with pytest.raises(ValueError, match=message) as error:
        loads(json.dumps(raw))
    assert str(error.value).startswith("tasks[0].episodes: ")

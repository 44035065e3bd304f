"""Scoring a policy on the suite's fixed evaluation seeds (`bbbench eval`).

from bbbench.evaluation import evaluate
from bbbench.policies import load_policy

evaluation = evaluate(load_policy("policy.zip"), ["bbbench/FlatBalance-v1"], episodes=10)
evaluation.document["tasks"][0]["aggregate"]["iqm"]
"""

from bbbench.evaluation.backends import BACKENDS
from bbbench.evaluation.harness import (
    LOCKSTEP,
    Evaluation,
    evaluate,
    results_document,
    select_tasks,
)
from bbbench.evaluation.play import PlayedEpisode
from bbbench.evaluation.results import dumps

__all__ = [
    "BACKENDS",
    "LOCKSTEP",
    "Evaluation",
    "PlayedEpisode",
    "dumps",
    "evaluate",
    "results_document",
    "select_tasks",
]

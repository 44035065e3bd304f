"""Policies `bbbench eval` scores: the built-in baselines, stable-baselines3 zips and ONNX
models.

from bbbench.policies import load_policy
policy = load_policy("pd")              # or "random", "reference", "policy.zip", "policy.onnx"

from bbbench.policies import export_onnx
export_onnx(agent.actor, "bbbench/FlatBalance-v1", "policy.onnx")  # any torch actor
"""

from bbbench.policies.controllers.pd import PDController
from bbbench.policies.errors import PolicyError, RefusedForSafety
from bbbench.policies.onnx.export import export_onnx, export_zip, onnx_bytes
from bbbench.policies.policy import fitting_tasks
from bbbench.policies.registry import (
    BUILTIN_POLICIES,
    Policy,
    classical_controller,
    load_policy,
    register_policy,
)

__all__ = [
    "BUILTIN_POLICIES",
    "PDController",
    "Policy",
    "PolicyError",
    "RefusedForSafety",
    "classical_controller",
    "export_onnx",
    "export_zip",
    "fitting_tasks",
    "load_policy",
    "onnx_bytes",
    "register_policy",
]

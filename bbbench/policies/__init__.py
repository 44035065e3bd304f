"""Policies `bbbench eval` scores: the built-in baselines and submitted stable-baselines3 zips.

from bbbench.policies import load_policy
policy = load_policy("pd")              # or "random", "reference", or "policy.zip"
"""

from bbbench.policies.errors import PolicyError, RefusedForSafety
from bbbench.policies.pd import PDController
from bbbench.policies.registry import (
    BUILTIN_POLICIES,
    Policy,
    fitting_tasks,
    load_policy,
    register_policy,
)

__all__ = [
    "BUILTIN_POLICIES",
    "PDController",
    "Policy",
    "PolicyError",
    "RefusedForSafety",
    "fitting_tasks",
    "load_policy",
    "register_policy",
]

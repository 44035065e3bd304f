"""Policies that ship with bbbench: baselines to compare submissions against."""

from bbbench.policies.pd import PDController

__all__ = ["PDController"]

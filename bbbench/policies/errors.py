"""The errors of reading and evaluating policies; every policy module imports them from here."""

from __future__ import annotations


class PolicyError(ValueError):
    """A policy that cannot be evaluated: a missing, unreadable or unsupported file, or a
    policy that fits no task. The CLI reports it in one line with exit code 2."""


class RefusedForSafety(PolicyError):
    """A submitted file refused unread, because reading it could run its code or cost
    unbounded memory or time."""

    def __init__(self, message: str) -> None:
        super().__init__(f"refused for safety: {message}")

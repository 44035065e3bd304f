"""Moved to `bbbench.envs.balance`; this name stays importable, as the same module."""

import sys

from bbbench.envs import balance

sys.modules[__name__] = balance

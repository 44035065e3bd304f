"""Moved to `bbbench.envs.tasks`; this name stays importable, as the same module."""

import sys

from bbbench.envs import tasks

sys.modules[__name__] = tasks

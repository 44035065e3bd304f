"""Moved to `bbbench.envs.multi`; this name stays importable, as the same module."""

import sys

from bbbench.envs import multi

sys.modules[__name__] = multi

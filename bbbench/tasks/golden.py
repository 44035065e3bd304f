"""Moved to `bbbench.dev.golden` (run it as `bbbench dev golden`); this name stays
importable, as the same module."""

import sys

from bbbench.dev import golden

sys.modules[__name__] = golden

"""Moved to `bbbench.dev.random_reference` (run it as `bbbench dev random-reference`); this
name stays importable, as the same module."""

import sys

from bbbench.dev import random_reference

sys.modules[__name__] = random_reference

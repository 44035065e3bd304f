"""Where a document was made: the Python, numpy and pybullet build it ran on.

A score is the same bits on CPython 3.10 to 3.13 (`bbbench.portable` defines what
Python or the CPU would otherwise decide). pybullet 3.2.7 publishes wheels up to
CPython 3.11 only; on 3.12 and later pip builds it from its source distribution,
and its physics then gives the same episodes. Results documents and the board record
the build they were made on, so that a reader, and `bbbench leaderboard check`, can
say which build made a number that another machine does not reproduce.
"""

from __future__ import annotations

import platform as _platform
from importlib import metadata
from typing import Any

import numpy as np

# The platform tags of published wheels; pip tags a wheel it built from an sdist with
# the bare platform (`linux_x86_64`), which PyPI refuses.
_PUBLISHED = ("manylinux", "musllinux", "macosx", "win")


def record() -> dict[str, str]:
    """This process's Python, numpy and pybullet, and how pybullet was installed."""
    return {
        "python": _platform.python_version(),
        "numpy": np.__version__,
        "pybullet": metadata.version("pybullet"),
        "pybullet_build": pybullet_build(),
    }


def pybullet_build() -> str:
    """'wheel' (a published wheel), 'source' (built from its sdist on this machine) or
    'unknown' (installed by other means: no wheel tags)."""
    try:
        wheel = metadata.distribution("pybullet").read_text("WHEEL") or ""
    except metadata.PackageNotFoundError:
        return "unknown"
    tags = [line.split(":", 1)[1].strip() for line in wheel.splitlines() if line.startswith("Tag:")]
    if not tags:
        return "unknown"
    if any(tag.rsplit("-", 1)[-1].startswith(_PUBLISHED) for tag in tags):
        return "wheel"
    return "source"


def described(made_on: dict[str, Any] | None) -> str:
    """'Python 3.13.0, numpy 2.4.6, pybullet 3.2.7 built from source'."""
    if not made_on:
        return "an unrecorded build"
    build = {
        "wheel": "from its wheel",
        "source": "built from source",
    }.get(made_on.get("pybullet_build"), "of unknown build")
    return (
        f"Python {made_on.get('python')}, numpy {made_on.get('numpy')}, "
        f"pybullet {made_on.get('pybullet')} {build}"
    )

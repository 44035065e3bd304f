"""Keep pybullet's C-level banners out of bbbench's output.

pybullet prints its build time on standard error when imported, and
`argv[0]=` on standard output when it connects, with C `printf`: Python's
`sys.stdout` and `sys.stderr` cannot catch them, and in a pipe they would come
out in the middle of a command's results or errors. Around those two calls,
file descriptors 1 and 2 point at /dev/null.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
from collections.abc import Iterator


def _flush_c_streams() -> None:
    with contextlib.suppress(AttributeError, OSError):
        ctypes.CDLL(None).fflush(None)


@contextlib.contextmanager
def c_output_silenced() -> Iterator[None]:
    """Discard what C code writes to descriptors 1 and 2 inside the block."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(AttributeError, ValueError, OSError):  # none, or closed
            stream.flush()
    saved = []
    try:
        for descriptor in (1, 2):
            saved.append((descriptor, os.dup(descriptor)))
    except OSError:  # a descriptor is not open: nothing of it to protect
        pass
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        for descriptor, _ in saved:
            os.dup2(devnull, descriptor)
        yield
    finally:
        _flush_c_streams()  # what C buffered goes to /dev/null, not to the restored streams
        for descriptor, copy in saved:
            os.dup2(copy, descriptor)
            os.close(copy)
        os.close(devnull)

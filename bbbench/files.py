"""Writing files so that a reader never sees half of one, and checking where they go first."""

from __future__ import annotations

import contextlib
import os
import signal
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path


def check_output_path(path: str | Path, flag: str) -> Path:
    """`ValueError` (saying what to do) unless a file can be written at `path`: a name
    that is not an existing directory, in an existing, writable directory. Checked before
    the work whose results it will hold, so a typo never costs them."""
    text = str(path)
    if not text.strip():
        raise ValueError(f"{flag} is empty: give a file name")
    path = Path(text)
    if text.endswith(os.sep) or path.is_dir():
        raise ValueError(f"{flag} {text}: is a directory; give a file name inside it")
    if path.exists() and not path.is_file():
        raise ValueError(f"{flag} {text}: exists and is not a regular file")
    folder = path.parent
    if not folder.is_dir():
        raise ValueError(f"{flag} {text}: no directory {folder}")
    try:  # the surest test of writability: create (exclusively) and remove a file there
        descriptor, probe = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".probe", dir=folder)
    except OSError as error:
        raise ValueError(
            f"{flag} {text}: cannot write in {folder} ({error.strerror or error})"
        ) from None
    os.close(descriptor)
    os.unlink(probe)
    return path


def check_distinct_outputs(outputs: Mapping[str, str | Path | None]) -> None:
    """`ValueError` if two of a command's outputs (flag: path, None for one not asked
    for) name one file: the second written would replace the first."""
    seen: dict[str, str] = {}
    for flag, path in outputs.items():
        if path is None:
            continue
        key = os.path.realpath(path)
        if key in seen:
            raise ValueError(
                f"{seen[key]} and {flag} both name {path}: the second would replace the "
                f"first; give each output a file of its own"
            )
        seen[key] = flag


@contextlib.contextmanager
def replacing(path: str | Path, suffix: str = "") -> Iterator[Path]:
    """A fresh temporary file beside `path` to write; on success it replaces `path` at
    once (`os.replace`), on failure it is removed and `path` is untouched.

    The name is unique and created exclusively (never an existing file, nor a link
    planted at a predictable name), so concurrent writers of one path never collide.
    `suffix` keeps an extension a writer needs (".gif").
    """
    path = Path(path)
    descriptor, temporary = tempfile.mkstemp(
        prefix=f".{path.name}.", suffix=f".partial{suffix}", dir=path.parent
    )
    os.close(descriptor)
    try:
        yield Path(temporary)
        os.chmod(temporary, 0o666 & ~_umask())  # as open() would have made it
        os.replace(temporary, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_atomic(path: str | Path, data: bytes) -> Path:
    """Write `data` to `path` through a temporary file beside it and an atomic rename:
    `path` holds either its old content or all of the new, never part of it."""
    path = Path(path)
    with replacing(path) as temporary, open(temporary, "wb") as file:
        file.write(data)
        file.flush()
        os.fsync(file.fileno())
    return path


def write_all_atomic(files: Mapping[Path, bytes]) -> None:
    """Write several files so that a reader sees all old or all new ones, up to a crash:
    each is written to a temporary file beside it first, and only then are they all
    renamed into place, with Ctrl-C and SIGTERM held until the renames are done."""
    temporaries: dict[Path, Path] = {}
    try:
        for path, data in files.items():
            descriptor, temporary = tempfile.mkstemp(
                prefix=f".{path.name}.", suffix=".partial", dir=path.parent
            )
            temporaries[path] = Path(temporary)
            with os.fdopen(descriptor, "wb") as file:
                file.write(data)
                file.flush()
                os.fsync(file.fileno())
            os.chmod(temporary, 0o666 & ~_umask())
        with _signals_held():
            for path, temporary in temporaries.items():
                os.replace(temporary, path)
    finally:
        for temporary in temporaries.values():
            with contextlib.suppress(FileNotFoundError):
                os.unlink(temporary)


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """Ctrl-C and SIGTERM wait until the block is done (main thread only)."""
    held = {signal.SIGINT, signal.SIGTERM}
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)

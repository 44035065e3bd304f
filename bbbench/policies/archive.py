"""Reading the members of an untrusted zip with bounded memory and one-line errors.

Python's `zipfile` trusts a member's header while inflating: it stops at the
size the header claims and then reports a CRC mismatch, and it raises a
different exception for each compression method, for encryption and for a
corrupt stream. `Archive` reads the central directory with `zipfile`, then
inflates each member itself:

- only the methods a stable-baselines3 zip uses (stored, deflated); an
  encrypted member, or bzip2 or lzma, is refused by name;
- a member never inflates past its allowed size nor past the size its header
  declares: more output than declared is reported as a zip bomb, less or a
  CRC mismatch as a corrupt or truncated file.
"""

from __future__ import annotations

import io
import struct
import zipfile
import zlib
from pathlib import Path

from bbbench.policies.errors import PolicyError, RefusedForSafety

_LOCAL_HEADER = struct.Struct("<4s5H3I2H")  # signature ... name length, extra length
_LOCAL_SIGNATURE = b"PK\x03\x04"
_METHODS = {zipfile.ZIP_STORED: "stored", zipfile.ZIP_DEFLATED: "deflated"}
_METHOD_NAMES = {zipfile.ZIP_BZIP2: "bzip2", zipfile.ZIP_LZMA: "lzma"}


def read_file(path: Path, limit: int, what: str) -> bytes:
    """A whole file of at most `limit` bytes; `PolicyError` naming it if it is missing,
    not a file, unreadable or too large."""
    if not path.exists():
        raise PolicyError(f"{path}: no such file")
    if not path.is_file():
        raise PolicyError(f"{path}: not a file (expected {what})")
    try:
        with open(path, "rb") as file:
            content = file.read(limit + 1)
    except OSError as error:
        raise PolicyError(f"{path}: cannot read it ({error.strerror or error})") from None
    if len(content) > limit:
        raise RefusedForSafety(f"{path}: more than the {limit} bytes allowed")
    return content


class Archive:
    """The members of a zip held in memory, each allowed at most `limits[name]` bytes.

    `required` members must be present; any member not in `limits` is refused. `kind` names
    what the zip should be, in errors: a stable-baselines3 model, or a mixed team's policy
    file (`bbbench.policies.onnx.team`).
    """

    def __init__(
        self,
        path: Path,
        content: bytes,
        limits: dict[str, int],
        required=(),
        kind: str = "a stable-baselines3 model",
    ) -> None:
        self.path = path
        self.content = content
        self.limits = limits
        self.kind = kind
        try:
            members = zipfile.ZipFile(io.BytesIO(content)).infolist()
        except (zipfile.BadZipFile, EOFError, ValueError, NotImplementedError) as error:
            raise PolicyError(f"{path}: not a readable zip ({error}); expected {kind}") from None
        names = [member.filename for member in members]
        for name in required:
            if name not in names:
                raise PolicyError(
                    f"{path}: no {name!r} member; expected a complete file, {kind} (is it "
                    f"truncated?)"
                )
        unexpected = sorted(set(names) - set(limits))
        if unexpected:
            raise RefusedForSafety(
                f"{path}: unexpected member(s) {unexpected} in the zip; {kind} holds only "
                f"{sorted(limits)}"
            )
        if len(set(names)) != len(names):
            raise RefusedForSafety(f"{path}: the zip names a member twice")
        for member in members:
            self._check(member)
        self.members = {member.filename: member for member in members}

    def _check(self, member: zipfile.ZipInfo) -> None:
        name, limit = member.filename, self.limits[member.filename]
        if member.flag_bits & 0x1:
            raise PolicyError(f"{self.path}: member {name!r} is encrypted; {self.kind} never is")
        if member.compress_type not in _METHODS:
            method = _METHOD_NAMES.get(member.compress_type, f"method {member.compress_type}")
            raise PolicyError(
                f"{self.path}: member {name!r} is compressed with {method}; {self.kind} is "
                f"stored or deflated"
            )
        if member.file_size > limit:
            raise RefusedForSafety(
                f"{self.path}: member {name!r} inflates to {member.file_size} bytes, more than "
                f"the {limit} allowed (a zip bomb?)"
            )

    def __contains__(self, name: str) -> bool:
        return name in self.members

    def read(self, name: str) -> bytes:
        """A member's bytes, inflating no more than its header declares."""
        member = self.members[name]
        start = member.header_offset
        header = self.content[start : start + _LOCAL_HEADER.size]
        if len(header) < _LOCAL_HEADER.size or header[:4] != _LOCAL_SIGNATURE:
            raise PolicyError(f"{self.path}: cannot find member {name!r} in the zip; truncated?")
        *_, name_length, extra_length = _LOCAL_HEADER.unpack(header)
        begin = start + _LOCAL_HEADER.size + name_length + extra_length
        raw = self.content[begin : begin + member.compress_size]
        if len(raw) < member.compress_size:
            raise PolicyError(f"{self.path}: member {name!r} is cut short; truncated?")
        declared = member.file_size
        if member.compress_type == zipfile.ZIP_STORED:
            data = raw[:declared]
        else:
            inflater = zlib.decompressobj(-zlib.MAX_WBITS)
            try:
                data = inflater.decompress(raw, declared + 1)
            except zlib.error as error:
                raise PolicyError(
                    f"{self.path}: member {name!r} is not a valid deflate stream ({error}); "
                    f"corrupt or truncated?"
                ) from None
            if len(data) > declared:
                raise RefusedForSafety(
                    f"{self.path}: member {name!r} inflates beyond the {declared} bytes its "
                    f"header declares (a zip bomb?)"
                )
        if len(data) != declared:
            raise PolicyError(
                f"{self.path}: member {name!r} holds {len(data)} of the {declared} bytes its "
                f"header declares; truncated?"
            )
        if zlib.crc32(data) != member.CRC:
            raise PolicyError(f"{self.path}: member {name!r} fails its CRC check; corrupt?")
        return data

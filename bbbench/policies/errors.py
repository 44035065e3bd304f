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


class NoContract(PolicyError):
    """An ONNX file whose metadata carries no bbbench contract, none being given either.
    `eval` and `export` take it from the command line; `sweep` and the board read it from
    the file only."""

    def __init__(self, message: str, file: str) -> None:
        super().__init__(message)
        self.file = file

    def for_file_only(self) -> str:
        """The message for a command that reads the contract from the file alone."""
        return (
            f"{self.file}: its metadata_props carry no bbbench contract, and this command "
            f"reads it from the file: write it in with `bbbench export {self.file} --out "
            f"OUT.onnx --observation N --action-space SPACE` and give OUT.onnx"
        )

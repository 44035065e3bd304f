"""The `bbbench` command: parses, calls, prints. One module per command, each with
`add_parser(commands)` and the function it runs; a command imports its subsystem
only when it runs, so `bbbench list` stays fast. `bbbench.cli.command` builds the
parser and runs it."""

from bbbench.cli.command import USAGE_ERROR, build_parser, main, run
from bbbench.cli.common import UsageError

__all__ = ["USAGE_ERROR", "UsageError", "build_parser", "main", "run"]

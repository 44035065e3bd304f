"""The `bbbench` command: the parser of every command, and how a run ends (exit codes,
one-line errors, Ctrl-C and SIGTERM)."""

from __future__ import annotations

import argparse
import gc
import os
import signal
import sys
from collections.abc import Sequence
from typing import NoReturn

import bbbench
from bbbench.cli import (
    dev,
    evaluate,
    export,
    leaderboard,
    listing,
    rollout,
    sweep,
    terrain,
    train,
)
from bbbench.cli.common import UsageError

USAGE_ERROR = 2  # exit code for user mistakes, as argparse uses
COMMANDS = (listing, rollout, terrain, evaluate, export, sweep, train, leaderboard, dev)


class Parser(argparse.ArgumentParser):
    """argparse's parser, whose mistakes are one line that points to `--help` (argparse
    prints the whole usage block first); its subcommands' parsers are of this class too."""

    def error(self, message: str) -> NoReturn:
        self.exit(USAGE_ERROR, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog="bbbench", description="A benchmark suite for two-wheeled balancing robots."
    )
    parser.add_argument("--version", action="version", version=f"bbbench {bbbench.__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS:
        command.add_parser(commands)
    return parser


class Terminated(BaseException):
    """SIGTERM, raised where the process is, so that cleanup runs as for Ctrl-C."""


def main(argv: Sequence[str] | None = None) -> int:
    """The `bbbench` command; with `argv` None it reads the process's arguments."""
    args = build_parser().parse_args(argv)
    args.written = []  # files the command has written, for the message if interrupted
    try:
        return args.run(args) or 0
    except UsageError as error:
        print(f"bbbench: error: {error}", file=sys.stderr)
        return USAGE_ERROR
    except (KeyboardInterrupt, Terminated) as interruption:
        what = "interrupted" if isinstance(interruption, KeyboardInterrupt) else "terminated"
        kept = f"wrote {', '.join(args.written)} only" if args.written else "nothing written"
        print(f"bbbench: {what}; {kept}", file=sys.stderr)
        code = 130 if isinstance(interruption, KeyboardInterrupt) else 143
    # The interrupted frames are free once the handler is left: what they held (a
    # training's multiprocessing locks) is collected now, as the quick exit skips teardown
    # and the resource tracker would warn of leaked semaphores.
    gc.collect()
    return code


def _terminate(signum, frame) -> NoReturn:
    raise Terminated


def run() -> NoReturn:
    """The `bbbench` process (the console script, `python -m bbbench`): `main()`, then
    exit at once.

    By then every file the command writes is closed (written atomically) and its
    workers or Ray are stopped; skipping the interpreter's teardown saves some
    0.2 s once `eval` has imported torch. An exception, or argparse's own exit,
    leaves the usual way. SIGTERM stops the command as Ctrl-C does (exit 143); output
    piped to a reader that leaves (`| head`) ends it quietly (exit 141).
    """
    signal.signal(signal.SIGTERM, _terminate)
    try:
        code = main()
        sys.stdout.flush()
    except BrokenPipeError:  # `bbbench list | head`: the reader left; Python's advice
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        code = 141  # 128 + SIGPIPE, as a shell reports a process a closed pipe stopped
    sys.stderr.flush()
    os._exit(code)

"""`python -m bbbench`: the same as the `bbbench` command."""

from bbbench.cli import run

run()

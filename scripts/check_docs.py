"""Check that the tables of the docs are what the scripts that make them print from
the files in baselines/ and leaderboards/ (run from the repository's top).

    python scripts/check_docs.py [--write]

A generated block is marked in the Markdown by the command that prints it:

    <!-- marl table: python scripts/marl_tables.py -->
    | ... the command's output ... |
    <!-- marl table: end -->

Each command is run again and its output compared with the block; `--write` puts the
output in place instead. The site's task pages (scripts/site_pages.py) are checked, or
written, with them. Exit 1, naming the blocks and pages that differ.
"""

from __future__ import annotations

import argparse
import re
import shlex
import subprocess
import sys
from pathlib import Path

DOCS = (Path("docs/baselines.md"), Path("docs/tasks.md"))
BLOCK = re.compile(
    r"^<!-- (?P<name>[^:>]+): (?P<command>python [^>]+?) -->\n"
    r"(?P<body>.*?)^<!-- (?P=name): end -->$",
    re.MULTILINE | re.DOTALL,
)


def blocks(text: str) -> list[re.Match]:
    """The generated blocks of a Markdown text, in order."""
    return list(BLOCK.finditer(text))


def printed(command: str) -> str:
    """What the block's command prints (with this interpreter), ending in one newline."""
    argv = shlex.split(command)
    done = subprocess.run([sys.executable, *argv[1:]], capture_output=True, text=True, check=True)
    return done.stdout.rstrip("\n") + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="write the outputs in place")
    args = parser.parse_args(argv)
    stale = []
    for path in DOCS:
        text = path.read_text()
        found = blocks(text)
        if not found:
            stale.append(f"{path}: no generated block")
        for match in reversed(found):  # from the end: earlier offsets stay valid
            output = printed(match["command"])
            if output == match["body"]:
                continue
            stale.append(f"{path}: the {match['name']} is not what `{match['command']}` prints")
            text = text[: match.start("body")] + output + text[match.end("body") :]
        if args.write:
            path.write_text(text)
    for problem in stale:
        print(problem, file=sys.stderr)
    pages = subprocess.run(
        [sys.executable, str(Path(__file__).with_name("site_pages.py"))]
        + (["--write"] if args.write else [])
    ).returncode
    return 1 if (stale or pages) and not args.write else 0


if __name__ == "__main__":
    sys.exit(main())

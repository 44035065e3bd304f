"""MkDocs hooks (mkdocs.yml): the leaderboard goes into the site, at /leaderboard/.

The board's files (leaderboards/: the page, its JSON, the results and the submissions,
but not its Markdown, which the page replaces) are added to the site's files as they
are, so one Pages site holds both, pages link to the board as to any other file, and
`mkdocs build --strict` fails on a link to a board file that does not exist.
"""

from __future__ import annotations

from pathlib import Path

from mkdocs.structure.files import File, Files

BOARD = Path(__file__).resolve().parent.parent / "leaderboards"
PREFIX = "leaderboard"


def on_files(files: Files, config) -> Files:
    for path in sorted(BOARD.rglob("*")):
        if path.is_file() and path.suffix != ".md" and "__pycache__" not in path.parts:
            uri = f"{PREFIX}/{path.relative_to(BOARD).as_posix()}"
            files.append(File.generated(config, uri, abs_src_path=str(path)))
    return files

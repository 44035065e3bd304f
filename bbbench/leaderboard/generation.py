"""Generating a board: score the submissions and write every file of the board, the same
bytes on every build."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bbbench.evaluation.profile import stored_records
from bbbench.evaluation.results import dumps
from bbbench.evaluation.team_sizes import sizes_file
from bbbench.files import write_all_atomic
from bbbench.leaderboard.board import Board, Scored, profile_file, score
from bbbench.leaderboard.page import FIGURES, README_FIGURE, page, readme_robustness_figure
from bbbench.leaderboard.ranking import leaderboard_document
from bbbench.leaderboard.submissions import Method, check_distinct, read_methods
from bbbench.leaderboard.verdicts import with_verdicts
from bbbench.leaderboard.views import markdown, with_baselines
from bbbench.portable import total

DOCUMENT = "bbbench-v0.json"
RESULTS = "results"
SUBMISSIONS = "submissions"
DEFAULT_BOARD = Board()  # what the `bbbench leaderboard` command plays


@dataclasses.dataclass(frozen=True)
class Built:
    """A generated leaderboard: its files (path inside the folder -> bytes) and what it
    took to make them."""

    files: dict[str, bytes]
    document: dict[str, Any]
    played: int  # episodes played (the rest came from stored results)
    episodes: int  # episodes on the board
    scored: list[Scored]  # each run's results, profiles and episodes played


def generate(
    root: str | Path,
    board: Board = DEFAULT_BOARD,
    cache: bool = True,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
    on_episodes: Callable[[int], None] | None = None,
    extra: Method | None = None,
    keys: dict[str, str | None] | None = None,
) -> Built:
    """Score the methods in `root` (and `extra`, a method not yet written there, or one
    with a run more) and generate every file of the board, in memory. With `cache`, a
    task result stored in `root/results` is reused when its key matches, and with `keys`
    (run slug -> the inputs key the board recorded) only for a run whose inputs are
    unchanged."""
    root = Path(root)
    methods = read_methods(root / SUBMISSIONS)
    if extra is not None:
        methods = sorted([*(m for m in methods if m.slug != extra.slug), extra], key=_slug)
        check_distinct([run for method in methods for run in method.runs])
    scored = score(
        [run for method in methods for run in method.runs],
        board,
        stored=root / RESULTS if cache else None,
        workers=workers,
        backend=backend,
        address=address,
        on_episodes=on_episodes,
        keys=keys,
    )
    built = _files(methods, scored, board)
    readme = root.parent / "README.md"  # the project's, where the board sits in a repository
    if readme.is_file():
        text = with_baselines(readme.read_text(encoding="utf-8"), built.document)
        if text is not None:
            built.files["../README.md"] = text.encode()
    baselines = root.parent / "docs" / "baselines.md"  # its verdicts, where it has them
    if baselines.is_file():
        text = with_verdicts(
            baselines.read_text(encoding="utf-8"), built.document, _results(scored)
        )
        if text is not None:
            built.files["../docs/baselines.md"] = text.encode()
    if (root / README_FIGURE).parent.is_dir():
        figure = readme_robustness_figure(built.document)
        if figure is not None:
            built.files[README_FIGURE] = figure.encode()
    return built


def _slug(method: Method) -> str:
    return method.slug


def _results(scored: list[Scored]) -> dict[str, dict[str, Any]]:
    """Each run's results document, by its slug."""
    return {entry.run.slug: entry.results for entry in scored}


def _files(methods: list[Method], scored: list[Scored], board: Board) -> Built:
    document = leaderboard_document(methods, scored, board)
    results = _results(scored)
    profiles = {
        **{
            profile_file(entry.run.slug, track): doc
            for entry in scored
            for track, doc in entry.profiles.items()
        },
        **{
            sizes_file(entry.run.slug, track): doc
            for entry in scored
            for track, doc in entry.sizes.items()
        },
    }
    files = {
        DOCUMENT: dumps(document).encode(),
        "README.md": markdown(document).encode(),
        **{name: text.encode() for name, text in page(document, results).items()},
        **{f"{RESULTS}/{slug}.json": dumps(doc).encode() for slug, doc in results.items()},
        **{f"{RESULTS}/{name}": dumps(doc).encode() for name, doc in profiles.items()},
    }
    episodes = total(
        block["aggregate"]["episodes"] for doc in results.values() for block in doc["tasks"]
    ) + total(len(records) for doc in profiles.values() for records in stored_records(doc))
    return Built(files, document, total(entry.played for entry in scored), episodes, scored)


def build(root: str | Path, board: Board = DEFAULT_BOARD, **options: Any) -> Built:
    """`generate`, then write the files into `root`: each atomically, and all of them
    only once every episode is scored (an interrupted build changes nothing).
    Results of runs that are gone are removed."""
    built = generate(root, board, **options)
    write(Path(root), built.files)
    return built


def write(root: Path, files: dict[str, bytes]) -> None:
    """Replace the generated files of the board in `root` by `files`, all at once; remove
    those no build writes any more (the results of runs that are gone, the
    figures of a track gone)."""
    for folder in (RESULTS, FIGURES):
        (root / folder).mkdir(parents=True, exist_ok=True)
    gone = stale(root, files)
    write_all_atomic({root / name: data for name, data in files.items()})
    for path in gone:
        path.unlink()


def stale(root: Path, files: dict[str, bytes]) -> list[Path]:
    """The generated files in `root` that are not among `files`: a build removes them."""
    return [
        path
        for folder, pattern in ((RESULTS, "*.json"), (FIGURES, "*.svg"))
        for path in sorted((root / folder).glob(pattern))
        if f"{folder}/{path.name}" not in files
    ]

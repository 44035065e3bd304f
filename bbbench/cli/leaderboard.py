"""`bbbench leaderboard build | check | add | show`."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from rich.console import Console
from rich.progress import MofNCompleteColumn, Progress
from rich.table import Table
from rich.text import Text

from bbbench.cli.common import UsageError, add_play_options
from bbbench.tasks.tracks import TRACKS


def add_parser(commands) -> None:
    board = commands.add_parser(
        "leaderboard",
        help="build, check, add to or show the leaderboard",
        description="The leaderboard: submissions in <root>/submissions, scored on every "
        "evaluation seed by the shipped harness, ranked with intervals.",
    )
    actions = board.add_subparsers(dest="action", required=True, metavar="ACTION")

    building = _with_common(
        actions.add_parser(
            "build", help="score every submission and write the board (JSON, Markdown, HTML)"
        )
    )
    building.add_argument(
        "--no-cache", action="store_true", help="play every episode again (ignore stored results)"
    )
    building.set_defaults(run=build)
    checking = _with_common(
        actions.add_parser(
            "check",
            help="check every number against the records, re-score changed runs, replay a "
            "random sample of the others; fail (exit 1) if any checked-in file differs",
            description="Compute every aggregate, rank and file of the board again from its "
            "per-episode records and compare them byte for byte; re-score in full every run "
            "whose inputs changed (its files, the versions, the tasks, the robustness "
            "protocol); replay a fixed budget of episodes of the others, drawn at random "
            "and shared evenly by the runs (bbbench.leaderboard.SPOT_BUDGET). --full "
            "plays every episode again.",
        )
    )
    checking.add_argument(
        "--full", action="store_true", help="play every episode of every run again"
    )
    checking.set_defaults(run=check)
    _add_parser_of_add(actions)
    showing = _with_common(actions.add_parser("show", help="print the ranked tables"), plays=False)
    showing.add_argument("--track", choices=tuple(TRACKS), help="one track (default all)")
    showing.set_defaults(run=show)


def track_name(track: str) -> str:
    """'single-bot', 'multi-bot' or 'wheel-legged': how the messages name a track."""
    return TRACKS[track].label


def _with_common(parser: argparse.ArgumentParser, plays: bool = True):
    """The options of every leaderboard action: the folder, and how episodes are played."""
    parser.add_argument(
        "--root", default="leaderboards", help="the leaderboard folder (default leaderboards)"
    )
    if plays:
        add_play_options(parser)
    return parser


def _add_parser_of_add(actions) -> None:
    """`bbbench leaderboard add`: the policy, its method's fields and its run's records."""
    adding = _with_common(
        actions.add_parser(
            "add",
            help="add a run of a method: check the policy, score it, write it and the board",
            description="Add a run (one policy, one training seed) to a method: a new one "
            "(its fields are required) or one on the board (its fields may be left out; "
            "those given must be its own, and the run's recipe must be its recipe). A "
            "controller is a method of one run, added without --seed.",
        )
    )
    adding.add_argument(
        "policy",
        metavar="POLICY",
        help="a stable-baselines3 .zip, an ONNX file with its contract (bbbench export), or a "
        "built-in's name",
    )
    adding.add_argument("--slug", required=True, help="the method's folder name, e.g. my-ppo")
    method = adding.add_argument_group("the method (for a new one)")
    method.add_argument("--name", help="display name")
    method.add_argument("--algorithm", help="e.g. PPO")
    method.add_argument("--author", action="append", help="an author (repeat for several)")
    method.add_argument(
        "--action-mode",
        choices=("discrete", "continuous"),
        help="checked against the policy (default: the policy's; discrete for a built-in)",
    )
    method.add_argument(
        "--track",
        action="append",
        choices=tuple(TRACKS),
        help="a track to be ranked on (repeat for several)",
    )
    method.add_argument("--licence", help="the policy's licence (SPDX), e.g. MIT")
    method.add_argument("--url", help="a paper, repository or write-up")
    method.add_argument("--notes", help="anything else a reader should know")
    method.add_argument("--date", help="the submission's own date, as you state it")
    run = adding.add_argument_group("the run")
    run.add_argument(
        "--seed",
        type=int,
        help="the run's training seed (leave out for a controller: a method of one run)",
    )
    run.add_argument(
        "--world-steps",
        type=int,
        required=True,
        help="the training budget in world steps (a multi-bot world step moves every bot "
        "once); 0 for a controller",
    )
    run.add_argument(
        "--trained-on",
        nargs="*",
        default=[],
        metavar="TASK",
        help="the task IDs it trained on",
    )
    run.add_argument(
        "--recipe", required=True, help="the recipe: its file, or its settings in words"
    )
    run.add_argument("--wall-time", required=True, help="training wall time, in words")
    run.add_argument("--hardware", required=True, help="the training machine, in words")
    run.add_argument(
        "--command",
        dest="training_command",
        required=True,
        help="the exact command that trained it",
    )
    run.add_argument("--run-notes", help="anything a reader should know of this run")
    adding.add_argument(
        "--vecnormalize", metavar="PKL", help="VecNormalize statistics the policy needs"
    )
    adding.set_defaults(run=add)


def _options(args: argparse.Namespace) -> dict:
    """The options every leaderboard command that plays episodes shares, checked."""
    from bbbench.evaluation.backends import check_ray  # lazy: bbbench.evaluation.backends

    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers must be at least 1, got {args.workers}")
    if args.address and args.backend != "ray":
        raise UsageError("--address names a Ray cluster: use it with --backend ray")
    if args.backend == "ray":
        try:
            check_ray(args.address)
        except ValueError as error:
            raise UsageError(str(error)) from None
    return {"workers": args.workers, "backend": args.backend, "address": args.address}


def _root(args: argparse.Namespace, board: bool = False):
    """The leaderboard folder `--root` names; with `board`, one that holds a board's
    submissions (what `check` checks)."""
    root = Path(args.root)
    if root.is_file():
        raise UsageError(f"--root {args.root}: is a file; give the leaderboard folder")
    if not root.is_dir():
        raise UsageError(
            f"--root {args.root}: no such folder (run from the repository's top, or give the "
            f"leaderboard folder)"
        )
    if board:
        from bbbench.leaderboard.generation import SUBMISSIONS  # lazy: bbbench.leaderboard

    if board and not (root / SUBMISSIONS).is_dir():
        raise UsageError(
            f"--root {args.root}: not a leaderboard folder (it has no submissions/ folder); "
            f"give the folder `bbbench leaderboard build` wrote"
        )
    return root


def _playing(what: str):
    """A live count of episodes played, on a terminal."""
    console = Console(stderr=True)
    progress = Progress(
        *Progress.get_default_columns()[:1],
        MofNCompleteColumn(),
        console=console,
        transient=True,
        disable=not console.is_terminal,
    )
    bar = progress.add_task(what, total=None)
    return progress, lambda count: progress.advance(bar, count)


def build(args: argparse.Namespace) -> int:
    from bbbench import leaderboard  # lazy: bbbench.leaderboard

    root = _root(args)
    options = _options(args)
    progress, on_episodes = _playing("episodes played")
    try:
        with progress:
            built = leaderboard.build(
                root,
                leaderboard.DEFAULT_BOARD,
                cache=not args.no_cache,
                on_episodes=on_episodes,
                **options,
            )
    except leaderboard.SubmissionError as error:
        raise UsageError(str(error)) from None
    except leaderboard.BuildError as error:
        print(f"bbbench: {error}; nothing written", file=sys.stderr)
        return 1
    args.written.append(str(root))
    tracks = ", ".join(
        f"{len(track['methods'])} methods on the {track_name(track['track'])} track"
        for track in built.document["tracks"]
    )
    print(
        f"wrote {root}: {tracks}; {built.episodes} episodes ({built.played} played, "
        f"{built.episodes - built.played} from stored results)"
    )
    return 0


def check(args: argparse.Namespace) -> int:
    from bbbench import leaderboard  # lazy: bbbench.leaderboard

    root = _root(args, board=True)
    options = _options(args)
    progress, on_episodes = _playing("episodes re-scored")
    try:
        with progress:
            checked = leaderboard.check(
                root, leaderboard.DEFAULT_BOARD, on_episodes=on_episodes, full=args.full, **options
            )
    except leaderboard.SubmissionError as error:
        raise UsageError(str(error)) from None
    except leaderboard.BuildError as error:
        print(f"bbbench: {error}", file=sys.stderr)
        return 1
    for note in checked.notes:
        print(f"bbbench: {note}", file=sys.stderr)
    if checked.problems:
        print(f"leaderboard check FAILED: {root} is not what its submissions give:")
        for problem in checked.problems:
            print(f"  {problem}")
        print("Rebuild with `bbbench leaderboard build` and commit what it writes.")
        return 1
    if args.full:
        how = f"{checked.episodes} episodes played again"
    else:
        rescored = ", ".join(checked.rescored) or "none"
        how = (
            f"every number recomputed from the records; re-scored in full (inputs changed): "
            f"{rescored}; {checked.spot_checked} episodes of the others replayed at random "
            f"(a budget of {leaderboard.SPOT_BUDGET} shared by the runs)"
        )
    print(
        f"leaderboard check ok: {checked.entries} runs, {checked.tasks} tasks; {how}; "
        f"{checked.seconds:.0f} s"
    )
    return 0


def add(args: argparse.Namespace) -> int:
    from bbbench import leaderboard  # lazy: bbbench.leaderboard

    root = _root(args)
    options = _options(args)
    given = {
        "name": args.name,
        "authors": args.author,
        "algorithm": args.algorithm,
        "action_mode": args.action_mode,
        "tracks": args.track,
        "url": args.url,
        "licence": args.licence,
        "notes": args.notes,
        "date": args.date,
    }
    method = {key: value for key, value in given.items() if value is not None}
    run = {
        "training_seed": args.seed,
        "recipe": {
            "world_steps": args.world_steps,
            "tasks": args.trained_on,
            "file": args.recipe,
        },
        "command": args.training_command,
        "wall_time": args.wall_time,
        "hardware": args.hardware,
        **({"notes": args.run_notes} if args.run_notes else {}),
    }
    progress, on_episodes = _playing("episodes played")
    try:
        with progress:
            built = leaderboard.add(
                root,
                args.policy,
                args.slug,
                method,
                run,
                vecnormalize=args.vecnormalize,
                board=leaderboard.DEFAULT_BOARD,
                on_episodes=on_episodes,
                **options,
            )
    except leaderboard.SubmissionError as error:
        raise UsageError(str(error)) from None
    except leaderboard.BuildError as error:
        print(f"bbbench: {error}; nothing written", file=sys.stderr)
        return 1
    args.written.append(str(root))
    for track in built.document["tracks"]:
        for entry in track["methods"]:
            if entry["slug"] == args.slug:
                place = (
                    f"ranks {entry['rank']} of {len(track['methods'])}"
                    if entry["rank"] is not None
                    else f"is listed, unranked: {entry['unranked']}"
                )
                print(f"{track_name(track['track'])} track: {args.slug} {place}")
    print(
        f"wrote {root / 'submissions' / args.slug} and the board: {built.played} episodes "
        f"played, {built.episodes - built.played} from stored results. Commit both."
    )
    return 0


def show(args: argparse.Namespace) -> int:
    from bbbench.leaderboard import DOCUMENT  # lazy: bbbench.leaderboard
    from bbbench.leaderboard.views import rows  # lazy: bbbench.leaderboard.views

    path = _root(args) / DOCUMENT
    try:
        document = json.loads(path.read_bytes())
        tracks = [t for t in document["tracks"] if args.track in (None, t["track"])]
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise UsageError(
            f"{path}: not a leaderboard ({error}); run `bbbench leaderboard build`"
        ) from None
    out = Console()
    if not out.is_terminal:
        out = Console(width=200)
    for track in tracks:
        header, body = rows(track)
        table = Table(title=track["title"].capitalize(), title_justify="left")
        for i, column in enumerate(header):
            table.add_column(column, justify="left" if i in (1, 2) else "right")
        for row in body:
            table.add_row(*map(Text, row))  # submitted names are text, not rich markup
        out.print(table)
    return 0

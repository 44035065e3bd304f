"""The documentation site (mkdocs.yml): its task pages are what the code and the board say,
it builds with no broken link or anchor, its runnable code blocks run, and a browser opens
it without a console error."""

from __future__ import annotations

import functools
import http.server
import importlib.util
import io
import os
import re
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

import bbbench
from bbbench.tasks.suite import SUITE, agent_spaces

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
RUN = "<!-- run -->"  # the marker of a runnable code block, on the line before its fence


def site_pages():
    spec = importlib.util.spec_from_file_location("site_pages", ROOT / "scripts" / "site_pages.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_task_pages_are_what_the_code_and_the_board_say():
    done = subprocess.run(
        [sys.executable, "scripts/site_pages.py"], cwd=ROOT, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr


def test_a_stale_page_is_named_and_a_stray_one_too(tmp_path, monkeypatch, capsys):
    pages = site_pages()
    monkeypatch.setattr(pages, "PAGES", tmp_path)
    monkeypatch.setattr(pages, "ROOT", tmp_path.parent)
    assert pages.main(["--write"]) == 0
    assert pages.main([]) == 0
    (tmp_path / "bumps.md").write_text("# Bumps, edited by hand\n")
    (tmp_path / "gone.md").write_text("# A task that left\n")
    assert pages.main([]) == 1
    err = capsys.readouterr().err
    assert "bumps.md: not what the code says now" in err
    assert "gone.md: no task has this page" in err


def table_after(text: str, heading: str) -> list[list[str]]:
    """The rows (cells) of the first Markdown table after `heading`."""
    section = text.split(f"\n{heading}\n", 1)[1]
    section = section.split("\n\n## ", 1)[0].split("\n\n### ", 1)[0]
    lines = [line for line in section.splitlines() if line.startswith("|")]
    return [[cell.strip() for cell in line.strip("|").split("|")] for line in lines[2:]]


@pytest.mark.parametrize("task_id", bbbench.list_tasks(latest=True))
def test_each_page_gives_its_tasks_own_spaces(task_id):
    task = SUITE[task_id]
    page = (DOCS / "environments" / f"{task.name.lower()}.md").read_text()
    # Each robot's spaces under its own heading on a mixed team's page.
    section = page.split("## Observation space", 1)[1]
    env = bbbench.make_parallel(task_id) if task.multi_agent else None
    for name, bots in task.robot_groups.items():
        if env is None:
            observation, action = agent_spaces(task_id, task.default_action_mode)
        else:
            agent = env.possible_agents[bots[0]]
            observation, action = env.observation_space(agent), env.action_space(agent)
        rows = table_after(
            page if not task.mixed else section,
            f"### {name}" if task.mixed else "## Observation space",
        )
        assert len(rows) == observation.shape[0]
        assert [int(row[0]) for row in rows] == list(range(observation.shape[0]))
        low = np.array([float(row[2]) for row in rows])
        high = np.array([float(row[3]) for row in rows])
        np.testing.assert_allclose(low, observation.low, rtol=1e-4)
        np.testing.assert_allclose(high, observation.high, rtol=1e-4)
        assert f"`{action}`" in page
        assert f"`Box({observation.shape[0]},)`" in page
    for entry in task.version_history:
        assert f"- {entry}" in page


@pytest.mark.parametrize("task_id", bbbench.list_tasks(latest=True))
def test_each_page_says_how_to_run_its_task_with_commands_that_are_taken(task_id):
    """The page's "Run it" block: its classical controller fits the task, and the training
    command's algorithm has a shipped recipe for it."""
    from bbbench.policies import load_policy
    from bbbench.training import check_request

    task = SUITE[task_id]
    page = (DOCS / "environments" / f"{task.name.lower()}.md").read_text()
    block = page.split("## Run it", 1)[1].split("```bash\n", 1)[1].split("```", 1)[0]
    (controller,) = re.findall(rf"^bbbench eval (\S+) --task {task_id}   #", block, re.M)
    assert load_policy(controller).mismatch(task_id) is None
    assert f"| Classical controller | `{controller}`" in page
    for algorithm in re.findall(rf"^bbbench train {task_id} --algo (\w+) --out", block, re.M):
        assert check_request([task_id], algorithm, None, None)[0] == [task_id]


@pytest.mark.parametrize("task_id", ["bbbench/MultiBalance-v1", "bbbench/FlatBalance-v1"])
def test_each_render_mode_a_page_lists_is_taken(task_id):
    task = SUITE[task_id]
    page = (DOCS / "environments" / f"{task.name.lower()}.md").read_text()
    (row,) = [line for line in page.splitlines() if line.startswith("| `render_mode` |")]
    modes = re.findall(r'`"(\w+)"`', row.split("|")[2])
    assert "rgb_array" in modes
    make = bbbench.make_parallel if task.multi_agent else bbbench.make
    for mode in modes:
        make(task_id, render_mode=mode).close()


def runnable_blocks() -> list[tuple[str, str, str]]:
    """(page, language, code) of every code block marked runnable in docs/."""
    found = []
    for path in sorted(DOCS.rglob("*.md")):
        text = path.read_text()
        for match in re.finditer(rf"^{re.escape(RUN)}\n```(\w+)\n(.*?)^```$", text, re.M | re.S):
            found.append((str(path.relative_to(DOCS)), match[1], match[2]))
    return found


def test_runnable_blocks_are_python_or_bash_and_some_exist():
    blocks = runnable_blocks()
    assert len(blocks) >= 3
    assert {language for _, language, _ in blocks} <= {"python", "bash"}
    marked = sum(path.read_text().count(RUN) for path in DOCS.rglob("*.md"))
    assert marked == len(blocks)  # no marker stands before anything but a code block


@pytest.mark.slow
@pytest.mark.parametrize(
    ("page", "language", "code"),
    runnable_blocks(),
    ids=[f"{page}:{i}" for i, (page, _, _) in enumerate(runnable_blocks())],
)
def test_every_runnable_code_block_runs(page, language, code, tmp_path):
    command = (
        [sys.executable, "-c", code]
        if language == "python"
        else ["bash", "-euo", "pipefail", "-c", code]
    )
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    done = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True, env=env)
    assert done.returncode == 0, f"{page}: {done.stderr[-2000:]}"


def build(out: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    return subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env=env,
    )


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site")
    done = build(out)
    assert done.returncode == 0, done.stderr
    return out


def test_the_site_builds_strict_with_the_board_and_the_api(site):
    assert (site / "index.html").is_file()
    assert (site / "leaderboard" / "index.html").read_bytes() == (
        ROOT / "leaderboards" / "index.html"
    ).read_bytes()
    assert not (site / "leaderboard" / "README").exists()  # the board's Markdown stays out
    api = (site / "reference" / "api" / "index.html").read_text()
    for name in (
        "bbbench.make",
        "bbbench.make_parallel",
        "bbbench.envs.balance.BalanceEnv",
        "bbbench.envs.multi.MultiBalanceEnv",
        "bbbench.evaluation.evaluate",
        "bbbench.policies.load_policy",
        "bbbench.policies.export_onnx",
    ):
        assert f'id="{name}"' in api
    for task_id in bbbench.list_tasks(latest=True):
        name = SUITE[task_id].name.lower()
        assert (site / "environments" / name / "index.html").is_file()


def test_a_broken_link_fails_the_build(tmp_path):
    page = DOCS / "guides" / "reproducibility.md"
    text = page.read_text()
    try:
        page.write_text(text + "\n[a page that is not there](nowhere.md)\n")
        done = build(tmp_path / "site")
    finally:
        page.write_text(text)
    assert done.returncode != 0
    assert "nowhere.md" in done.stderr


class QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format, *args) -> None:
        pass


@pytest.fixture(scope="module")
def served(site):
    handler = functools.partial(QuietHandler, directory=str(site))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()


@pytest.mark.parametrize(
    ("path", "heading"),
    [("/", "bbbench"), ("/environments/swap/", "Swap"), ("/reference/api/", "API reference")],
)
def test_a_browser_opens_the_pages_with_no_console_error(chromium, served, path, heading):
    chromium.get_log("browser")  # what earlier pages logged
    chromium.get(served + path)
    assert chromium.find_element("css selector", "article h1").text.startswith(heading)
    links = chromium.find_elements("css selector", "a[href*='leaderboard/']")
    assert links  # the board is linked from every page (the navigation)
    errors = [entry for entry in chromium.get_log("browser") if entry["level"] == "SEVERE"]
    assert errors == []


def test_a_screenshot_of_a_task_page_shows_its_picture(chromium, served):
    from PIL import Image

    chromium.get(served + "/environments/bumps/")
    image = Image.open(io.BytesIO(chromium.get_screenshot_as_png()))
    width, height = chromium.execute_script("return [window.innerWidth, window.innerHeight]")
    assert image.size == (width, height)  # the viewport of the fixture's 1400 x 1000 window
    assert width == 1400
    pixels = np.asarray(image.convert("RGB")).reshape(-1, 3)
    assert len(np.unique(pixels, axis=0)) > 1000  # the page and its frame, not a blank
    frame = chromium.find_element("css selector", "article img")
    assert frame.size["width"] > 200
    assert chromium.execute_script("return arguments[0].naturalWidth", frame) > 0  # loaded


def test_the_readme_is_a_front_page_whose_links_all_resolve():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 200
    assert "<!-- ci: main-command -->" in text
    assert "<!-- ci: test-command -->" in text
    assert "mkdocs serve" in text
    links = re.findall(r"\]\(((?!https?://)[^)#\s]+)", text)
    assert len(links) > 10
    missing = [link for link in links if not (ROOT / link).exists()]
    assert missing == []

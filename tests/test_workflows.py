"""The GitHub workflows, validated offline: GitHub's schema (check-jsonschema's vendored
copy) and zizmor's security audit (actions pinned by commit, no credentials persisted,
least permissions)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
WORKFLOWS = sorted((ROOT / ".github" / "workflows").glob("*.yml"))
LEADERBOARD = ROOT / ".github" / "workflows" / "leaderboard.yml"


def tool(name: str) -> str:
    found = shutil.which(name) or str(Path(sys.executable).with_name(name))
    if not Path(found).exists():
        pytest.fail(f"{name} is not installed: it is in the test extra")
    return found


def test_the_leaderboard_workflow_exists():
    assert LEADERBOARD in WORKFLOWS


@pytest.mark.parametrize("workflow", WORKFLOWS, ids=lambda p: p.name)
def test_a_workflow_follows_githubs_schema(workflow):
    result = subprocess.run(
        [tool("check-jsonschema"), "--builtin-schema", "vendor.github-workflows", str(workflow)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.parametrize("workflow", WORKFLOWS, ids=lambda p: p.name)
def test_zizmor_finds_nothing_of_medium_or_high_severity(workflow):
    result = subprocess.run(
        [
            tool("zizmor"),
            "--offline",
            "--format",
            "json",
            "--min-severity",
            "medium",
            str(workflow),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    findings = json.loads(result.stdout or "[]")
    assert findings == [], json.dumps(findings, indent=1)[:2000]


def test_the_zizmor_audit_catches_an_unpinned_action_that_keeps_credentials(tmp_path):
    bad = tmp_path / "bad.yml"
    text = LEADERBOARD.read_text()
    text = text.replace(
        "actions/checkout@11bd71901bbe5b1630ceea73d27597364c9af683", "actions/checkout@v4"
    )
    text = text.replace("        with:\n          persist-credentials: false\n", "")
    bad.write_text(text)
    result = subprocess.run(
        [tool("zizmor"), "--offline", "--format", "json", str(bad)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    rules = {finding["ident"] for finding in json.loads(result.stdout)}
    assert {"unpinned-uses", "artipacked"} <= rules


def test_pull_requests_check_with_the_readmes_install_and_main_publishes():
    text = LEADERBOARD.read_text()
    readme = (ROOT / "README.md").read_text()
    install = readme.split("<!-- ci: main-command -->", 1)[1].split("```bash\n", 1)[1]
    install = install.split(" && ", 1)[0]
    assert f"run: {install}\n" in text
    assert "run: bbbench leaderboard check\n" in text
    assert "actions/upload-artifact@" in text
    assert "actions/deploy-pages@" in text
    assert "refs/heads/main" in text


def test_main_publishes_the_site_built_strict_with_the_board_inside():
    text = LEADERBOARD.read_text()
    publish = text.split("  publish:\n", 1)[1].split("  deploy:\n", 1)[0]
    assert "run: mkdocs build --strict\n" in publish
    assert "path: site/\n" in publish  # mkdocs.yml's site_dir, the board copied in
    assert "site_dir: site\n" in (ROOT / "mkdocs.yml").read_text()
    for watched in ('"docs/**"', '"mkdocs.yml"', '"leaderboards/**"'):
        assert watched in text.split("push:", 1)[1].split("workflow_dispatch", 1)[0]

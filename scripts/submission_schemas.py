"""Write docs/submission-schema.json and docs/run-schema.json from the fields bbbench checks
(`bbbench.leaderboard.fields`); tests/test_leaderboard.py holds the files to them."""

from pathlib import Path

from bbbench.leaderboard.fields import schema_files

if __name__ == "__main__":
    docs = Path(__file__).resolve().parent.parent / "docs"
    for name, text in schema_files().items():
        (docs / name).write_text(text, encoding="utf-8")
        print(f"wrote docs/{name}")

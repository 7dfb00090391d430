"""Where things may live: the rules of the layout, checked on the source tree.

Each rule is a scan of the source files (``envs/``, ``league/``, ``bench/``) and a test
that the scan finds a planted violation, so a rule that stopped matching would fail.
Tests themselves are not scanned: they read ``league.db`` with their own SQL on
purpose, as a check of what is on disk that does not go through the store's code.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SOURCE_DIRS = ("envs", "league", "bench")

# Running SQL: the sqlite3 module, a cursor's execute calls, or an SQL statement in a string.
SQL = re.compile(
    r"\bimport sqlite3\b|\bfrom sqlite3\b|\.execute(many|script)?\("
    r"|\bSELECT\b[^\n]*\bFROM\b|\bINSERT\s+(OR\s+\w+\s+)?INTO\b|\bUPDATE\s+\w+\s+SET\b|\bDELETE\s+FROM\b"
    r"|\b(CREATE|ALTER|DROP)\s+TABLE\b"
)
SQL_HOME = "league/state/store.py"


def source_files(root: Path) -> list[Path]:
    return sorted(p for d in SOURCE_DIRS for p in (root / d).rglob("*.py"))


def violations(root: Path, pattern: re.Pattern, allowed: set[str]) -> list[str]:
    """``path:line: text`` of every line matching ``pattern`` outside the ``allowed`` files."""
    found = []
    for path in source_files(root):
        relative = path.relative_to(root).as_posix()
        if relative in allowed:
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if pattern.search(line):
                found.append(f"{relative}:{number}: {line.strip()}")
    return found


def plant(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return root


def test_sql_only_in_the_store():
    assert violations(ROOT, SQL, {SQL_HOME}) == []


def test_the_sql_scan_finds_sql_outside_the_store(tmp_path):
    root = plant(tmp_path, {
        SQL_HOME: 'import sqlite3\nROWS = "SELECT id FROM players"\n',
        "league/report.py": 'rows = store.db.execute("SELECT outcome, SUM(count) FROM matches").fetchall()\n',
        "bench/learning.py": "import sqlite3\n",
        "envs/core.py": 'Q = "UPDATE players SET env_steps = 0"\n',
        "league/status.py": '"""Selects the players from the store."""\n',  # prose, not SQL
    })
    assert [v.split(":")[0] for v in violations(root, SQL, {SQL_HOME})] == [
        "bench/learning.py", "envs/core.py", "league/report.py",
    ]


def test_the_package_version_is_pyprojects():
    import tomllib

    import league

    assert league.__version__ == tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]

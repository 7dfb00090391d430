"""The type check: mypy as ``pyproject.toml``'s ``[tool.mypy]`` sets it, strict on ``envs/`` and ``league/core/``.

One mypy run over the tree must pass, and a run that reads a planted error in each strict
package instead of the file on disk must fail on both, so a check that stopped reaching them
(a changed ``files`` list, a lost override) would fail too. mypy keeps its cache in the
git-ignored ``.mypy_cache/``: a fresh clone's first run reads the typed libraries it imports
(numpy, torch, Ray) in about 30 s, a later one about 1 s; the planted run rechecks only the
files it changes and those that import them.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TIMEOUT_S = 600

# One file of each strict package gets an error only a strict setting reports (a function
# without annotations), then one that any setting reports (a str where an int is declared).
STRICT_FILES = ("envs/rewards.py", "league/core/pfsp.py")
PLANT = {
    "def planted(x):": "error: Function is missing a type annotation  [no-untyped-def]",
    "    return x": None,
    "PLANTED: int = 'one'": "error: Incompatible types in assignment",
}


def mypy(*args: str) -> subprocess.CompletedProcess[str]:
    """``python -m mypy`` in the repository root, reading ``pyproject.toml``'s settings."""
    return subprocess.run(
        [sys.executable, "-m", "mypy", *args], cwd=ROOT, capture_output=True, text=True, timeout=TIMEOUT_S
    )


def test_mypy_passes_with_the_projects_settings():
    result = mypy()
    assert result.returncode == 0, result.stdout + result.stderr


def test_mypy_finds_a_planted_error_in_each_strict_package(tmp_path):
    shadows, expected = [], []
    for name in STRICT_FILES:
        lines = (ROOT / name).read_text().splitlines()
        for planted, error in PLANT.items():
            lines.append(planted)
            if error:
                expected.append(f"{name}:{len(lines)}: {error}")
        shadow = tmp_path / name.replace("/", "_")
        shadow.write_text("\n".join(lines) + "\n")
        shadows += ["--shadow-file", name, str(shadow)]
    result = mypy(*shadows)
    assert result.returncode == 1, result.stdout + result.stderr
    missing = [line for line in expected if line not in result.stdout]
    assert not missing, result.stdout

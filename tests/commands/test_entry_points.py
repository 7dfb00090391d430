"""Every command (league's, and ``envs.match``): its console script names an importable ``main``,
``--help`` and ``--version`` work."""

from __future__ import annotations

import importlib
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import league

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
COMMANDS = sorted(p.stem for p in (ROOT / "league").glob("*.py") if 'if __name__ == "__main__":' in p.read_text())


def entry_point(target: str):
    module, function = target.split(":")
    return getattr(importlib.import_module(module), function)


def test_every_command_has_a_console_script():
    league_scripts = [target for target in SCRIPTS.values() if target.startswith("league.")]
    assert sorted(target.split(":")[0].removeprefix("league.") for target in league_scripts) == COMMANDS
    assert {name: target for name, target in SCRIPTS.items() if target not in league_scripts} == {
        "envs-match": "envs.match:main",  # the scripted players' table
    }
    assert all(callable(entry_point(target)) for target in SCRIPTS.values())


@pytest.mark.parametrize("name", sorted(SCRIPTS))
def test_help_of_every_command(name, capsys):
    with pytest.raises(SystemExit) as exit_:
        entry_point(SCRIPTS[name])(["--help"])
    assert exit_.value.code == 0
    assert f"usage: python -m {SCRIPTS[name].split(':')[0]}" in capsys.readouterr().out


@pytest.mark.parametrize("name", sorted(SCRIPTS))
def test_version_of_every_command(name, capsys):
    with pytest.raises(SystemExit) as exit_:
        entry_point(SCRIPTS[name])(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out.strip().endswith(league.__version__)


@pytest.mark.parametrize("module", ["league.status", "envs.match"])
def test_a_command_runs_as_a_module(module):
    done = subprocess.run([sys.executable, "-m", module, "--version"], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0 and done.stdout.strip() == f"python -m {module} {league.__version__}"

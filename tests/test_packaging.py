"""What an install gets: one version, every package, the configs inside the wheel.

The last test builds the wheel (``pip wheel``, no network) and installs it into a fresh venv
that borrows this venv's dependencies, then looks a config up by name from outside the
source tree, as ``pip install target-defense-league`` would be used.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import sysconfig
import tomllib
from pathlib import Path

import league

ROOT = Path(__file__).resolve().parent.parent
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_the_version_is_kept_in_one_place():
    project = PYPROJECT["project"]
    assert "version" not in project and "version" in project["dynamic"]
    assert PYPROJECT["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "league.__version__"}
    literal = re.compile(rf"""["'][^"'\n]*\b{re.escape(league.__version__)}\b[^"'\n]*["']""")
    elsewhere = [
        str(path.relative_to(ROOT))
        for folder in ("envs", "league")
        for path in (ROOT / folder).rglob("*.py")
        if path != ROOT / "league" / "__init__.py" and literal.search(path.read_text())
    ]
    assert elsewhere == []


def test_the_wheel_lists_every_package_and_ships_the_configs():
    setuptools = PYPROJECT["tool"]["setuptools"]
    on_disk = {
        ".".join(init.parent.relative_to(ROOT).parts)
        for folder in ("envs", "league")
        for init in (ROOT / folder).rglob("__init__.py")
    }
    assert set(setuptools["packages"]) == on_disk | {"league.configs"}
    assert setuptools["package-dir"] == {"league.configs": "configs"}
    assert setuptools["package-data"] == {"league.configs": ["*.yaml"]}


def test_an_installed_wheel_finds_a_config_by_name_and_runs(tmp_path):
    source = tmp_path / "source"
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        (source / name).parent.mkdir(exist_ok=True)
        shutil.copy(ROOT / name, source / name)
    for folder in ("envs", "league", "configs"):
        shutil.copytree(ROOT / folder, source / folder, ignore=shutil.ignore_patterns("__pycache__"))
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check"]
    subprocess.run(
        [*pip, "wheel", "--no-deps", "--no-build-isolation", "--no-index", "-q", "-w", tmp_path / "dist", source],
        check=True, capture_output=True,
    )
    [wheel] = (tmp_path / "dist").glob("target_defense_league-*.whl")
    assert wheel.name.startswith(f"target_defense_league-{league.__version__}-")

    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", venv], check=True)
    python = venv / "bin" / "python"
    purelib = subprocess.run(
        [python, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"], check=True, capture_output=True, text=True
    ).stdout.strip()
    # The dependencies from this venv (a path, so its .pth files, the editable install's among them, are not read).
    (Path(purelib) / "borrowed.pth").write_text(sysconfig.get_path("purelib") + "\n")
    subprocess.run([*pip, "--python", python, "install", "--no-deps", "--no-index", "-q", wheel], check=True, capture_output=True)

    outside = tmp_path / "elsewhere"
    outside.mkdir()
    found = subprocess.run(
        [python, "-c", "import league, league.config as c; print(league.__file__); print(c.resolve_path('smoke'))"],
        cwd=outside, check=True, capture_output=True, text=True,
    ).stdout.split()
    assert found == [f"{purelib}/league/__init__.py", f"{purelib}/league/configs/smoke.yaml"]
    helped = subprocess.run([venv / "bin" / "league-run", "--help"], cwd=outside, capture_output=True, text=True)
    assert helped.returncode == 0 and "--config" in helped.stdout, helped.stderr[-2000:]


def test_constraints_pin_every_dependency_the_project_names():
    pins = {}
    for line in (ROOT / "constraints.txt").read_text().splitlines():
        if line and not line.startswith("#"):
            name, _, version = line.partition("==")
            pins[re.sub(r"[-_.]+", "-", name).lower()] = version
    named = PYPROJECT["project"]["dependencies"] + [d for extra in PYPROJECT["project"]["optional-dependencies"].values() for d in extra]
    names = {re.sub(r"[-_.]+", "-", re.match(r"[A-Za-z0-9_.-]+", d).group()).lower() for d in named}
    assert sorted(names - set(pins)) == []
    assert pins["torch"] == "2.13.0"  # no local version: it matches the CPU build (2.13.0+cpu) and PyPI's

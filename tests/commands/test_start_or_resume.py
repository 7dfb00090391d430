"""The containers' entrypoint, without containers: a new run in a missing or empty directory,
the resume of the run a directory holds (a second start of a finished run exits 0), and a
run of another config refused."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from league import start_or_resume
from league.start_or_resume import league_run_args

ROOT = Path(__file__).resolve().parents[2]


def test_a_missing_or_empty_directory_gets_a_new_run(tmp_path):
    for run_dir in (tmp_path / "new", tmp_path / "empty"):
        if run_dir.name == "empty":
            run_dir.mkdir()
            (run_dir / "run.lock").write_text("")  # left by an earlier start that was refused: no run
        assert league_run_args("smoke", run_dir, ["seed=4"], "auto") == [
            "--config", "smoke", "--run-dir", str(run_dir), "--set=seed=4", "--address", "auto"
        ]


def test_a_directory_holding_a_run_is_resumed(run_copy, tiny_run):
    config = str(tiny_run.parent / "tiny.yaml")
    assert league_run_args(config, run_copy, [], None) == ["--resume", str(run_copy)]
    assert league_run_args(config, run_copy, [], "auto") == ["--resume", str(run_copy), "--address", "auto"]


def test_a_run_of_another_config_is_refused_naming_the_keys(run_copy, tiny_run, capsys, monkeypatch):
    def no_exec(*args):
        raise AssertionError(f"exec {args}")  # (a real exec would replace pytest's process)

    monkeypatch.setattr(start_or_resume.os, "execv", no_exec)
    config = str(tiny_run.parent / "tiny.yaml")
    assert start_or_resume.main(["--config", config, "--run-dir", str(run_copy), "--set", "seed=4", "--set", "ppo.lr=0.01"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error: ") and "(ppo.lr, seed differ)" in err, err


def test_a_second_start_of_a_finished_run_resumes_it_and_exits_0(run_copy, tiny_run):
    done = subprocess.run(
        [sys.executable, "-m", "league.start_or_resume", "--config", str(tiny_run.parent / "tiny.yaml"),
         "--run-dir", str(run_copy)],
        capture_output=True, text=True, cwd=ROOT, timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert f"resuming the run in {run_copy}" in done.stderr
    assert f"{run_copy} is finished" in done.stdout and "nothing to resume" in done.stdout

"""A study's runs as Ray Tune trials (``league.studies.trials``): trained, a killed one resumed,
finished ones reused from the restored experiment and, without it, from their run directories;
and the study's progress line."""

import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from league.state.run_dir import EVALUATION_FILE, lock_holder
from league.state.store import LeagueStore
from league.studies import runs
from league.study import main as study_main
from league.study import study_run
from league.studies.trials import (
    DONE, StudyProgress, TrainingRun, TUNE_DIR, param, progress_line, train_runs, training_exit_code,
)

# Checkpoints every iteration (a killed run resumes from its first); no learning curves (quicker).
OVERRIDES = ["checkpoint_every=1", "evaluation.curve_every_env_steps=0"]


def test_the_time_left_comes_from_the_runs_trained_here():
    # 10 runs, 3 done: 2 reused, 1 trained in 600 s; 7 left one at a time: 70 min.
    assert progress_line(10, 3, 2, [600.0], 41 * 60, 1) == "study: 3 of 10 runs done (2 reused), 41 min elapsed, about 70 min left"
    # Two at a time, runs of 600 and 1200 s (900 on average): 7 left are 4 rounds, 60 min.
    assert progress_line(10, 3, 1, [600.0, 1200.0], 30, 2).endswith("30 s elapsed, about 60 min left")
    # More at a time than runs left: one round.
    assert progress_line(4, 3, 0, [60.0, 60.0, 60.0], 300, 8).endswith("about 60 s left")
    assert progress_line(5, 2, 2, [], 5, 1) == "study: 2 of 5 runs done (2 reused), 5 s elapsed, time left unknown until a run has trained here"
    assert progress_line(2, 2, 1, [4000.0], 4000, 1) == "study: 2 of 2 runs done (1 reused), 67 min elapsed"
    assert "about 2 h 00 min left" in progress_line(3, 1, 0, [3600.0], 3600, 1)


def committed_iterations(run_dir):
    if not (run_dir / "league.db").exists():
        return []
    store = LeagueStore(run_dir)
    try:
        return [row["iteration"] for row in store.iteration_rows()]
    finally:
        store.close()


def kill_after_first_iteration(run_dir, stop):
    """SIGKILL the ``league.run`` training ``run_dir`` once its first iteration is committed."""
    while not stop.is_set():
        holder = lock_holder(run_dir) if committed_iterations(run_dir) else None
        if holder:
            os.kill(holder, signal.SIGKILL)
            return
        time.sleep(0.3)


def test_runs_train_as_trials_a_killed_one_resumes_and_finished_ones_are_reused(ray_instance, tiny_run, tmp_path, capsys):
    config = str(tiny_run.parent / "tiny.yaml")
    out = tmp_path / "study"
    runs = [study_run(out, config, seed, OVERRIDES) for seed in (3, 4)]
    first, second = (run.run_dir for run in runs)

    # Both trained as trials; the second killed after its first iteration: the study fails, the first run is kept.
    stop = threading.Event()
    killer = threading.Thread(target=kill_after_first_iteration, args=(second, stop), daemon=True)
    killer.start()
    try:
        assert training_exit_code(runs, out) == 1  # a command's exit code: run it again to resume
    finally:
        stop.set()
        killer.join()
    said, error = capsys.readouterr()
    assert re.fullmatch(r"error: training tiny, seed 4 failed \(league.run exit -9; its output: .*\); run this command again "
                        r"to resume\n", error, flags=re.DOTALL)
    assert said.splitlines()[0] == "study: 0 of 2 runs done (0 reused), 0 s elapsed, time left unknown until a run has trained here"
    assert f"training tiny, seed 3 -> {first}" in said and f"training tiny, seed 4 -> {second}" in said
    assert "study: 1 of 2 runs done (0 reused), " in said and " left" in said.split("study: 1 of 2")[1].splitlines()[0]
    assert (first / "evaluation.md").exists() and not (second / "evaluation.md").exists()
    assert "iteration" in runs[0].log.read_text()  # the run's output went to its log
    first_db = (first / "league.db").stat().st_mtime

    # Again: the experiment restored; the finished trial is not run again, the errored one resumes.
    done = train_runs(runs, out)
    said = capsys.readouterr().out
    assert said.splitlines()[0].startswith("study: 1 of 2 runs done (1 reused), ")
    assert f"resuming {second}" in said and "training tiny" not in said and "reusing" not in said
    assert said.splitlines()[-1].startswith("study: 2 of 2 runs done (1 reused), ")
    assert committed_iterations(second) == [1, 2, 3, 4]  # continued, nothing done twice
    assert (first / "league.db").stat().st_mtime == first_db
    assert [(d.run.run_dir, d.reused) for d in done] == [(first, False), (second, False)]

    # The study command on them: restored again, nothing runs; then its tables.
    finals = [(d / "evaluation.md").stat().st_mtime for d in (first, second)]  # (the tables add test games to league.db)
    args = ["--config", config, "--seeds", "3", "4", "--out", str(out), "--episodes", "8",
            *[item for override in OVERRIDES for item in ("--set", override)]]
    assert study_main(args) == 0
    said = capsys.readouterr().out
    assert said.startswith("study: 2 of 2 runs done (2 reused), ") and "resuming" not in said and "reusing" not in said
    assert "| team-v1 | scripted-lead_intercept |" in said

    # The Tune state lost: a new experiment, whose trials find both runs finished in their directories.
    shutil.rmtree(out / TUNE_DIR)
    assert study_main(args) == 0
    said = capsys.readouterr().out
    assert f"reusing {first} (finished)" in said and f"reusing {second} (finished)" in said
    assert "study: 2 of 2 runs done (2 reused)" in said and "training tiny" not in said
    assert [(d / "evaluation.md").stat().st_mtime for d in (first, second)] == finals
    assert committed_iterations(first) == committed_iterations(second) == [1, 2, 3, 4]


def test_a_run_finished_before_the_study_counts_once_whatever_the_form_of_its_path(tmp_path, monkeypatch, capsys):
    """A study given a relative ``--out`` names its runs relatively; its trials name them absolutely."""
    monkeypatch.chdir(tmp_path)
    runs = [TrainingRun("smoke", Path(f"out/seed-{s}"), (), f"seed {s}", Path(f"out/seed-{s}.log")) for s in (1, 2)]
    (tmp_path / "out" / "seed-1").mkdir(parents=True)
    (tmp_path / "out" / "seed-1" / EVALUATION_FILE).write_text("done")
    progress = StudyProgress(runs, parallel=1, on_cluster=False)
    progress.setup()
    reused = SimpleNamespace(config={"run": param(runs[0])}, last_result={DONE: True, "reused": True, "seconds": 0.0})
    progress.on_trial_complete(0, [], reused)
    assert capsys.readouterr().out.splitlines()[-1].startswith("study: 1 of 2 runs done (1 reused)")


def test_a_run_writing_to_its_log_says_its_newest_progress_line_while_it_trains(tmp_path, monkeypatch):
    """A study's runs write to their logs; the study passes on each run's share of the budget and time left."""
    monkeypatch.setattr(runs, "PROGRESS_EVERY_S", 0.2)
    log, heard = tmp_path / "run.log", []
    script = ("import sys, time\n"
              "print('12:00:00 phase 1/2 attacker | iter 1 | 8192 env steps in all | 10% of 80,000, 9 s left', flush=True)\n"
              "time.sleep(1.0)\n")
    runs.run_saying_progress([sys.executable, "-c", script], log, "smoke, seed 1", heard.append)
    assert heard and heard[-1] == "smoke, seed 1: 12:00:00 phase 1/2 attacker | iter 1 | 8192 env steps in all | 10% of 80,000, 9 s left"
    with pytest.raises(subprocess.CalledProcessError):
        runs.run_saying_progress([sys.executable, "-c", "raise SystemExit(3)"], log, "x", heard.append)

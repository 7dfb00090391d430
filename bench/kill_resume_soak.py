"""Kill-and-resume soak: random SIGKILL / SIGTERM / SIGINT during one run, each followed by ``--resume``.

``python bench/kill_resume_soak.py --kills 20`` starts ``league.run --config smoke`` in a
fresh directory and, until it has been stopped ``--kills`` times, waits for a random
moment and sends a random one of the three signals, then resumes the run; the last
resume runs to the end. A kill lands either at a random point of the iteration cycle
(0 to ``--cycle-seconds`` after the run commits a new iteration: sampling, learning,
snapshot, checkpoint or commit) or at a random time after launch (start-up, restoring).
SIGINT goes to the process group (Ctrl-C), SIGTERM to the run's process (a scheduler),
SIGKILL to the group (the whole job dies).

At the end it checks what the league relies on: ``PRAGMA integrity_check``, iterations
numbered 1..n without gap or repeat, the running episode total equal to the recorded
training matches, every snapshot version present once per side and reward method with
its saved module, no ``.partial`` left. It prints one line per kill and a summary; the
exit code is 1 if a check failed. A process that exits by itself (not killed) is
reported and resumed, as a user would.
"""

from __future__ import annotations

import argparse
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

from league.state.store import DB_NAME, DamagedStoreError, LeagueStore

SIGNALS = {"SIGKILL": signal.SIGKILL, "SIGTERM": signal.SIGTERM, "SIGINT": signal.SIGINT}
EXPECTED_EXIT = {"SIGKILL": -9, "SIGTERM": 143, "SIGINT": 130}


def read_store(run_dir: Path, read):
    """``read(store)`` on the run's league database, opened for this one read."""
    store = LeagueStore(run_dir)
    try:
        return read(store)
    finally:
        store.close()


def committed(run_dir: Path) -> int:
    try:
        return read_store(run_dir, lambda store: (store.last_iteration() or {}).get("iteration", 0))
    except (FileNotFoundError, DamagedStoreError):  # not created yet, or removed for a fresh start
        return 0


def launch(args: list[str], log) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "league.run", *args], stdout=log, stderr=subprocess.STDOUT, start_new_session=True
    )


def wait_for_moment(proc: subprocess.Popen, run_dir: Path, rng: random.Random, cycle_seconds: float,
                    startup_seconds: float) -> str:
    """Sleep until a random moment of this process's life; returns where it landed."""
    if rng.random() < 0.25:
        delay = rng.uniform(0, startup_seconds)
        deadline = time.monotonic() + delay
        while time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.05)
        return f"{delay:.1f} s after launch"
    start = committed(run_dir)
    while committed(run_dir) <= start and proc.poll() is None:
        time.sleep(0.1)
    delay = rng.uniform(0, cycle_seconds)
    deadline = time.monotonic() + delay
    while time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    return f"{delay:.1f} s after iteration {committed(run_dir)} was committed"


def last_error(log_path: Path) -> str:
    lines = [line.strip() for line in log_path.read_text().splitlines() if line.strip()]
    return lines[-1][:200] if lines else ""


def check(run_dir: Path) -> list[str]:
    """What is wrong with the finished run (empty: nothing)."""
    problems = []
    store = LeagueStore(run_dir)
    try:
        integrity = store.integrity_check()
        numbers = [row["iteration"] for row in store.iteration_rows()]
        episodes = store.last_iteration()["episodes"]
        matches = sum(row.count for row in store.outcome_rows("training"))
        snapshots = [(p.side, p.reward_method or 0, p.version, p.checkpoint) for p in store.players(kind="snapshot")]
    finally:
        store.close()
    if integrity != "ok":
        problems.append(f"integrity_check: {integrity}")
    if numbers != list(range(1, len(numbers) + 1)):
        problems.append(f"iterations not consecutive: {numbers}")
    if episodes != matches:
        problems.append(f"episode total {episodes} != recorded training matches {matches}")
    by_line = Counter((side, method) for side, method, _, _ in snapshots)
    for (side, method), count in by_line.items():
        versions = sorted(v for s, m, v, _ in snapshots if (s, m) == (side, method))
        if versions != list(range(count)):
            problems.append(f"{side} m{method} snapshot versions {versions}: lost or duplicated")
    missing = [path for _, _, _, path in snapshots if not (run_dir / path / "module_state.pkl").exists()]
    if missing:
        problems.append(f"snapshots without a saved module: {missing}")
    partial = list(run_dir.rglob("*.partial"))
    if partial:
        problems.append(f"left-over partial files: {partial}")
    if not (run_dir / "evaluation.md").exists():
        problems.append("no evaluation.md: the run did not finish")
    return problems


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="smoke")
    parser.add_argument("--run-dir", type=Path, default=Path("runs") / f"soak-{time.strftime('%Y%m%d-%H%M%S')}")
    parser.add_argument("--kills", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cycle-seconds", type=float, default=6.0, help="kill at most this long after a commit")
    parser.add_argument("--startup-seconds", type=float, default=40.0, help="or at most this long after launch")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="passed to league.run (e.g. a longer run: league.phase_env_steps=96000)")
    args = parser.parse_args()
    rng = random.Random(args.seed)
    run_dir = args.run_dir.resolve()
    log_path = run_dir.with_name(run_dir.name + ".log")
    started = time.perf_counter()
    exits: Counter = Counter()
    unexpected: list[str] = []
    failures: list[str] = []  # exits nobody caused (e.g. Ray's start-up timeout on an overloaded machine)
    with log_path.open("w") as log:
        new_run = ["--config", args.config, "--run-dir", str(run_dir), *(f"--set={o}" for o in args.overrides)]
        proc = launch(new_run, log)
        kills = 0
        while kills < args.kills:
            moment = wait_for_moment(proc, run_dir, rng, args.cycle_seconds, args.startup_seconds)
            if proc.poll() == 0:  # finished before the kill
                print(f"the run finished before kill {kills + 1}", flush=True)
                break
            if proc.poll() is not None:  # failed by itself: say so, and resume (a user would retry)
                failures.append(f"before kill {kills + 1}: exit {proc.returncode}: {last_error(log_path)}")
                print(f"run failed by itself before kill {kills + 1}: {failures[-1]}", flush=True)
                if len(failures) > args.kills:
                    break
                proc = launch(["--resume", str(run_dir)], log)
                continue
            name = rng.choice(sorted(SIGNALS))
            if name == "SIGTERM":
                os.kill(proc.pid, SIGNALS[name])
            else:
                os.killpg(proc.pid, SIGNALS[name])
            code = proc.wait()
            kills += 1
            exits[(name, code)] += 1
            # A run killed before its first checkpoint has nothing to resume: it exits 2 on --resume
            # (or removed its directory); start it anew then.
            fresh = not (run_dir / DB_NAME).exists() or not read_store(run_dir, LeagueStore.checkpoints)
            print(f"kill {kills:2d}: {name:7s} {moment}; exit {code}; at iteration {committed(run_dir)}", flush=True)
            if code not in (EXPECTED_EXIT[name], 0, 2):
                unexpected.append(f"kill {kills}: {name} gave exit {code}")
            if fresh:
                shutil.rmtree(run_dir, ignore_errors=True)
                proc = launch(new_run, log)
            else:
                proc = launch(["--resume", str(run_dir)], log)
        code = proc.wait()
        if code != 0:
            unexpected.append(f"the last resume exited {code}")
    problems = check(run_dir) + unexpected
    iterations = committed(run_dir)
    print(
        f"{kills} kills ({', '.join(f'{n} {s}->exit {c}' for (s, c), n in sorted(exits.items()))}), "
        f"{iterations} iterations, {len(failures)} exits nobody caused, {time.perf_counter() - started:.0f} s; "
        f"log {log_path}"
    )
    for failure in failures:
        print(f"  not caused by a kill: {failure}")
    print("all checks passed" if not problems else "PROBLEMS:\n  " + "\n  ".join(problems))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())

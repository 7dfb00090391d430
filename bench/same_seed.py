"""Same config, same seed, same run: train a config twice (and, with ``--kills K``, a third
time killed K times at random moments with SIGKILL and resumed), then list where the run
directories differ (``league.state.run_dir.run_differences``: the league database but its
wall-clock columns, and every saved player's weights).

    python bench/same_seed.py --config smoke --kills 2
    python bench/same_seed.py --config smoke --set resources.num_env_runners=2 --set resources.num_cpus_per_env_runner=0.5
    python bench/same_seed.py --config selfplay_league --set league.selfplay_phases=3 --set league.phase_env_steps=100000

Exit code 0 when every run is the first one, 1 otherwise.
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from league.state.run_dir import run_differences
from league.state.store import DamagedStoreError, LeagueStore


def iterations(run_dir: Path) -> int:
    try:
        store = LeagueStore(run_dir)
    except (FileNotFoundError, DamagedStoreError):  # not there yet
        return 0
    try:
        return store.iteration_count()
    finally:
        store.close()


def start(args: list[str], log: Path) -> subprocess.Popen:
    with open(log, "a") as out:
        return subprocess.Popen([sys.executable, "-m", "league.run", *args], stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True)


def train(args: list[str], run_dir: Path) -> float:
    started = time.perf_counter()
    proc = start([*args, "--run-dir", str(run_dir)], run_dir.with_suffix(".log"))
    if proc.wait() != 0:
        sys.exit(f"{run_dir} failed: see {run_dir.with_suffix('.log')}")
    return time.perf_counter() - started


def train_with_kills(args: list[str], run_dir: Path, total: int, kills: int, seed: int) -> None:
    """Kill the run ``kills`` times with SIGKILL, each somewhere in a random iteration, and resume it."""
    moments = random.Random(seed)
    log = run_dir.with_suffix(".log")
    proc = start([*args, "--run-dir", str(run_dir)], log)
    for after in sorted(moments.sample(range(1, max(2, total - 1)), min(kills, max(1, total - 2)))):
        while iterations(run_dir) < after and proc.poll() is None:
            time.sleep(0.05)
        time.sleep(moments.uniform(0.0, 1.5))
        if proc.poll() is not None:
            break
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        print(f"killed after {iterations(run_dir)} committed iterations; resuming", flush=True)
        proc = start(["--resume", str(run_dir)], log)
    if proc.wait() != 0:
        sys.exit(f"{run_dir} failed: see {log}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="smoke")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--kills", type=int, default=0, help="a third run killed this many times and resumed")
    parser.add_argument("--out", type=Path, help="where the run directories go (default: a new temporary one)")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="same_seed-"))
    out.mkdir(parents=True, exist_ok=True)
    league_args = ["--config", args.config, *[a for item in args.overrides for a in ("--set", item)]]
    first, second = out / "first", out / "second"
    print(f"first run: {train(league_args, first):.0f} s, {iterations(first)} iterations", flush=True)
    print(f"second run: {train(league_args, second):.0f} s", flush=True)
    runs = [second]
    if args.kills:
        killed = out / "killed"
        train_with_kills(league_args, killed, iterations(first), args.kills, seed=0)
        runs.append(killed)
    same = True
    for run in runs:
        differences = run_differences(first, run)
        print(f"{run.name} against first: " + ("the same run" if not differences else "\n  " + "\n  ".join(differences)))
        same = same and not differences
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())

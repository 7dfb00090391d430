"""Is learning real? Train the paper's protocol and compare on 1000 fixed games.

``python bench/learning.py --config attacker_method2`` runs ``league.run`` (phase 1: the
attacker against the scripted team for 10,000 episodes; phase 2: the team against that
frozen attacker), then prints, from the run's evaluation, with 95% Wilson intervals:

* the trained attacker vs the scripted team, against the scripted lead-intercept
  attacker and the untrained attacker (version 0) on the same games;
* the trained attacker vs the trained team, against the same attacker vs the
  scripted team (did phase 2 lower its win rate?).
"""

from __future__ import annotations

import argparse
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

from envs.agents import Outcome
from league.evaluation import wilson_interval

ATTACKER_WINS = tuple(o.label for o in Outcome if o.attacker_wins)


def rate(db: sqlite3.Connection, attacker: str, team: str) -> tuple[float, tuple[float, float], int]:
    """Attacker win rate of the evaluation pair given by player names."""
    names = {}
    for pid, side, kind, version, method, sa, st, sd in db.execute(
        "SELECT id, side, kind, version, reward_method, scripted_attacker, scripted_targeter, scripted_defender FROM players"
    ):
        if kind == "scripted":
            name = f"scripted-{sa}" if side == "attacker" else f"scripted-{st}+{sd}"
        elif kind == "snapshot":
            name = f"attacker-m{method}-v{version}" if side == "attacker" else f"team-v{version}"
        else:
            continue
        names[name] = pid
    rows = db.execute(
        "SELECT outcome, SUM(count) FROM matches WHERE source = 'evaluation' AND attacker = ? AND team = ? GROUP BY outcome",
        (names[attacker], names[team]),
    ).fetchall()
    games = sum(n for _, n in rows)
    wins = sum(n for outcome, n in rows if outcome in ATTACKER_WINS)
    return wins / games, wilson_interval(wins, games), games


def show(label: str, value: tuple[float, tuple[float, float], int]) -> None:
    r, (low, high), n = value
    print(f"{label:58s} {r:.3f} [{low:.3f}, {high:.3f}] over {n}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="attacker_method2")
    parser.add_argument("--run-dir", type=Path)
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--skip-training", action="store_true", help="only read an existing run directory")
    args = parser.parse_args()
    run_dir = args.run_dir or Path("runs") / f"bench-learning-{args.config}"
    started = time.perf_counter()
    if not args.skip_training:
        command = [sys.executable, "-m", "league.run", "--config", args.config, "--run-dir", str(run_dir)]
        for item in args.overrides:
            command += ["--set", item]
        subprocess.run(command, check=True)
    wall = time.perf_counter() - started
    db = sqlite3.connect(run_dir / "league.db")
    method = db.execute("SELECT reward_method FROM players WHERE kind = 'learner' AND side = 'attacker'").fetchone()[0]
    trained, untrained = f"attacker-m{method}-v1", f"attacker-m{method}-v0"
    scripted_team, trained_team = "scripted-avoid_attacker+pure_pursuit", "team-v1"
    episodes = db.execute("SELECT episodes, env_steps FROM iterations ORDER BY iteration DESC LIMIT 1").fetchone()
    print(f"run {run_dir}: {episodes[0]} training episodes, {episodes[1]} env steps, wall {wall:.0f} s")
    vs_scripted = rate(db, trained, scripted_team)
    lead = rate(db, "scripted-lead_intercept", scripted_team)
    initial = rate(db, untrained, scripted_team)
    vs_trained_team = rate(db, trained, trained_team)
    show(f"trained {trained} vs scripted team", vs_scripted)
    show("scripted lead_intercept vs scripted team", lead)
    show(f"untrained {untrained} vs scripted team", initial)
    show(f"trained {trained} vs trained {trained_team}", vs_trained_team)
    print(f"attacker at least as good as lead intercept: {vs_scripted[0] >= lead[0]}")
    print(f"attacker beats its untrained policy, intervals apart: {vs_scripted[1][0] > initial[1][1]}")
    print(f"trained team lowers the attacker, intervals apart: {vs_trained_team[1][1] < vs_scripted[1][0]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

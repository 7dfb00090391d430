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
import subprocess
import sys
import time
from pathlib import Path

from league.analysis.statistics import wilson_interval
from league.core.payoff import aggregate
from league.state.store import LeagueStore


def rate(store: LeagueStore, attacker: str, team: str) -> tuple[float, tuple[float, float], int]:
    """Attacker win rate of the evaluation pair given by player names (frozen players)."""
    ids = {p.name: p.id for p in store.players() if p.kind != "learner"}
    wins, games = aggregate(store.newest_evaluation_rows())[(ids[attacker], ids[team])]
    return wins / games, wilson_interval(wins, games), games


def show(label: str, value: tuple[float, tuple[float, float], int]) -> None:
    r, (low, high), n = value
    print(f"{label:58s} {r:.3f} [{low:.3f}, {high:.3f}] over {n}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="attacker_method2_paper")
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
    store = LeagueStore(run_dir)
    method = store.players(side="attacker", kind="learner")[0].reward_method
    trained, untrained = f"attacker-m{method}-v1", f"attacker-m{method}-v0"
    scripted_team = next(p for p in store.players(side="team", kind="scripted") if p.is_paper_team).name
    trained_team = "team-v1"
    last = store.last_iteration()
    print(f"run {run_dir}: {last['episodes']} training episodes, {last['env_steps']} env steps, wall {wall:.0f} s")
    vs_scripted = rate(store, trained, scripted_team)
    lead = rate(store, "scripted-lead_intercept", scripted_team)
    initial = rate(store, untrained, scripted_team)
    vs_trained_team = rate(store, trained, trained_team)
    store.close()
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

"""Do a config's trained players beat the scripted ones? ``python bench/beats_scripted.py --config attacker_method2``.

Trains the config once per seed (``league.run``, one run directory per seed under ``--out``;
a finished run is reused, an unfinished one resumed), then reads each run's final evaluation
(every attacker against every team on the fixed games) and prints, per seed and as the mean
over seeds with a 95% bootstrap interval over the seeds:

* the final attacker (the newest snapshot of each reward method) against each scripted team,
  beside the best scripted attacker against that team;
* the final team (the newest team snapshot) against each scripted attacker and the final
  attackers, beside the best scripted team against that attacker (the lowest attacker win rate);
* the Nash weight of the trained players (snapshots from version 1 on) on each side of the run's
  final meta-game;
* with ``--untrained``, also the final team against its untrained version (``team-v0``)
  against every attacker of the league, and each final attacker against its own version 0
  against every team.

A row is a "win" for the trained player when its 95% Wilson interval lies wholly on the good
side of the best scripted player's. Extra ``--set`` overrides go to every run.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np

from league.analysis.nash import league_meta_game
from league.analysis.statistics import bootstrap_interval, wilson_interval
from league.core.payoff import aggregate
from league.state.run_dir import open_run

TRAINED = ("snapshot", "exploiter_snapshot")


def train(config: str, run_dir: Path, seed: int, overrides: list[str]) -> None:
    """Run (or resume, or reuse) one seed's league."""
    if (run_dir / "evaluation.md").exists():
        return
    if (run_dir / "league.db").exists():
        command = ["-m", "league.run", "--resume", str(run_dir)]
    else:
        command = ["-m", "league.run", "--config", config, "--run-dir", str(run_dir), "--set", f"seed={seed}"]
        for override in overrides:
            command += ["--set", override]
    print("$ python", " ".join(command), flush=True)
    subprocess.run([sys.executable, *command], check=True)


def rate(table: dict, attacker, team) -> tuple[float, float, float]:
    wins, games = table[(attacker.id, team.id)]
    return (wins / games, *wilson_interval(wins, games))


def comparison(player, against, mine, reference, theirs) -> dict:
    """A row: ``player``'s attacker win rate ``mine`` against ``against`` beside ``reference``'s
    ``theirs``, better for an attacker when higher and for a team when lower, intervals apart."""
    higher, lower = mine[1] > theirs[2], mine[2] < theirs[1]
    return dict(player=player.name, against=against.name, rate=mine, best=reference.name, best_rate=theirs,
                better=higher if player.side == "attacker" else lower, worse=lower if player.side == "attacker" else higher)


def measure(run_dir: Path, untrained: bool = False) -> list[dict]:
    """One row per comparison of a trained player with the best scripted player (and, with
    ``untrained``, with its own version 0)."""
    _, store = open_run(run_dir)
    try:
        players, evaluations = store.players(), store.newest_evaluation_rows()
    finally:
        store.close()
    table = aggregate(evaluations)
    scripted_attackers = [p for p in players if p.side == "attacker" and p.kind == "scripted"]
    scripted_teams = [p for p in players if p.side == "team" and p.kind == "scripted"]
    final_attackers = {}
    for p in players:
        if p.side == "attacker" and p.kind == "snapshot":
            final_attackers[p.reward_method] = p
    team_snapshots = [p for p in players if p.side == "team" and p.kind == "snapshot"]
    final_team = team_snapshots[-1]
    rows = []
    for attacker in final_attackers.values():
        for team in scripted_teams:
            best = max(scripted_attackers, key=lambda a: rate(table, a, team)[0])
            rows.append(comparison(attacker, team, rate(table, attacker, team), best, rate(table, best, team)))
    for attacker in scripted_attackers + list(final_attackers.values()):
        best = min(scripted_teams, key=lambda t: rate(table, attacker, t)[0])
        rows.append(comparison(final_team, attacker, rate(table, attacker, final_team), best, rate(table, attacker, best)))
    if untrained:
        attackers = [p for p in players if p.side == "attacker" and p.kind in ("scripted", *TRAINED)]
        teams = [p for p in players if p.side == "team" and p.kind in ("scripted", *TRAINED)]
        first_team = team_snapshots[0]
        for attacker in attackers:
            rows.append(comparison(final_team, attacker, rate(table, attacker, final_team), first_team,
                                   rate(table, attacker, first_team)))
        for attacker in final_attackers.values():
            first = next(p for p in attackers if p.kind == "snapshot" and p.reward_method == attacker.reward_method)
            for team in teams:
                rows.append(comparison(attacker, team, rate(table, attacker, team), first, rate(table, first, team)))
    meta, why_not = league_meta_game(players, evaluations)
    if meta is None:
        raise SystemExit(f"{run_dir}: no meta-game ({why_not})")
    for side, chosen, weights in (("attacker", meta.attackers, meta.equilibrium.row_mixture), ("team", meta.teams, meta.equilibrium.column_mixture)):
        # Version 0 is a learner before training (with ``ppo.attacker_prior`` it plays lead intercept).
        trained = sum(w for p, w in zip(chosen, weights) if p.kind in TRAINED and p.version > 0)
        rows.append(dict(player=f"trained {side}s", against="Nash weight", rate=(trained, trained, trained),
                         best="", best_rate=None, better=trained > 0, worse=trained == 0))
    return rows


def verdict(row: dict) -> str:
    return "better" if row["better"] else "worse" if row["worse"] else "even"


def report(per_seed: dict[int, list[dict]]) -> str:
    seeds = sorted(per_seed)
    lines = [
        "| trained player | against | " + " | ".join(f"seed {s}" for s in seeds)
        + " | mean over seeds [bootstrap 95%] | reference player | its rate (seed mean) |",
        "| --- | --- | " + " | ".join("---" for _ in seeds) + " | --- | --- | --- |",
    ]
    for index, first in enumerate(per_seed[seeds[0]]):
        cells, values, best_values = [], [], []
        for s in seeds:
            row = per_seed[s][index]
            value, low, high = row["rate"]
            values.append(value)
            if row["best_rate"] is None:
                cells.append(f"{value:.3f}")
            else:
                best_values.append(row["best_rate"][0])
                cells.append(f"{value:.3f} [{low:.3f}, {high:.3f}] {verdict(row)}")
        low, high = bootstrap_interval(values)
        best = f"{np.mean(best_values):.3f}" if best_values else ""
        lines.append(f"| {first['player']} | {first['against']} | " + " | ".join(cells)
                     + f" | {np.mean(values):.3f} [{low:.3f}, {high:.3f}] | {first['best']} | {best} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", required=True)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--out", type=Path, default=Path("runs/beats_scripted"))
    parser.add_argument("--untrained", action="store_true",
                        help="also compare each final player with its untrained version 0")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()
    name = Path(args.config).stem
    per_seed = {}
    for seed in args.seeds:
        run_dir = args.out / name / f"seed-{seed}"
        train(args.config, run_dir, seed, args.overrides)
        per_seed[seed] = measure(run_dir, args.untrained)
    print(report(per_seed))


if __name__ == "__main__":
    main()

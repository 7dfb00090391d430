"""A run's report: ``python -m league.report --run-dir DIR`` writes ``DIR/report/report.md`` and PNGs.

Sections: the Table 1 analogue next to the paper's numbers, the payoff matrix heat map,
ratings and learner win rates over training, episode returns, and 3D trajectories of
won and lost episodes for each side (the analogues of the paper's Fig. 3 and Fig. 4).
Evaluation numbers come from the league database; a pair the run never evaluated is
played now on the fixed evaluation games.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from envs.agents import Outcome
from envs.match import play
from envs.render import plot_episode
from envs.scenarios import evaluation_scenarios
from league.config import RunConfig, saved_run_config
from league.evaluation import agents_of, evaluate_pairs, wilson_interval
from league.payoff import aggregate
from league.players import Player
from league.run_dir import RunDirError, open_run
from league.store import LeagueStore

ATTACKER_WINS = {o.label for o in Outcome if o.attacker_wins}
# The paper's Table 1: A's winning percentage over 100 test rounds per method.
PAPER_TABLE_1 = {1: 0.48, 2: 0.6253, 3: 0.5763}
PAPER_TEAM = ("avoid_attacker", "pure_pursuit")
TRAJECTORY_GAMES = 200


def evaluation_payoff(store: LeagueStore, run: RunConfig, run_dir: Path, needed: list[tuple[Player, Player]]):
    """``{(attacker id, team id): (attacker wins, games)}`` of the newest evaluation, filling gaps."""
    latest = store.db.execute("SELECT MAX(iteration) FROM matches WHERE source = 'evaluation'").fetchone()[0]
    rows = store.db.execute(
        "SELECT attacker, team, outcome, SUM(count) FROM matches WHERE source = 'evaluation' AND iteration = ? "
        "GROUP BY attacker, team, outcome",
        (latest if latest is not None else -1,),
    ).fetchall()
    table = aggregate(rows, ATTACKER_WINS)
    missing = [(a, t) for a, t in needed if (a.id, t.id) not in table]
    for r in evaluate_pairs(run.game, run_dir, missing, run.evaluation.episodes):
        table[(r.attacker.id, r.team.id)] = (r.attacker_wins, r.games)
    return table


def table_one(store: LeagueStore, payoff, players: list[Player]) -> str:
    team = next((p for p in players if p.kind == "scripted" and (p.scripted_targeter, p.scripted_defender) == PAPER_TEAM), None)
    lines = ["| method | attacker | win rate vs the paper's scripted team | 95% interval | games | paper (100 rounds) |",
             "| --- | --- | --- | --- | --- | --- |"]
    latest = {}
    for p in players:
        if p.side == "attacker" and p.kind == "snapshot":
            latest[p.reward_method] = p
    for method, attacker in sorted(latest.items()):
        wins, games = payoff.get((attacker.id, team.id), (0, 0)) if team else (0, 0)
        low, high = wilson_interval(wins, games)
        rate = f"{wins / games:.3f}" if games else "not evaluated"
        lines.append(f"| {method} | {attacker.name} | {rate} | [{low:.3f}, {high:.3f}] | {games} | {PAPER_TABLE_1[method]} |")
    return "\n".join(lines) + "\n"


def heat_map(payoff, attackers: list[Player], teams: list[Player], out: Path) -> None:
    grid = np.full((len(attackers), len(teams)), np.nan)
    for i, a in enumerate(attackers):
        for j, t in enumerate(teams):
            wins, games = payoff.get((a.id, t.id), (0, 0))
            if games:
                grid[i, j] = wins / games
    fig, ax = plt.subplots(figsize=(3.0 + 1.1 * len(teams), 2.5 + 0.45 * len(attackers)))
    image = ax.imshow(grid, cmap="RdBu_r", vmin=0, vmax=1, aspect="auto")
    ax.set_xticks(range(len(teams)), [t.name for t in teams], rotation=45, ha="right", fontsize=7)
    ax.set_yticks(range(len(attackers)), [a.name for a in attackers], fontsize=7)
    for i in range(len(attackers)):
        for j in range(len(teams)):
            if not np.isnan(grid[i, j]):
                ax.text(j, i, f"{grid[i, j]:.2f}", ha="center", va="center", fontsize=6)
    fig.colorbar(image, label="attacker win rate")
    ax.set_title("payoff (evaluation)")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def line_plot(series: dict[str, tuple[list, list]], ylabel: str, title: str, out: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 4))
    for label, (x, y) in sorted(series.items()):
        ax.plot(x, y, label=label, lw=1.2)
    ax.set_xlabel("iteration")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    if series:
        ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def learner_win_rates(store: LeagueStore, players: list[Player]) -> dict[str, tuple[list, list]]:
    learners = {p.id: p for p in players if p.kind == "learner"}
    rows = store.db.execute(
        "SELECT iteration, attacker, team, outcome, SUM(count) FROM matches WHERE source = 'training' "
        "GROUP BY iteration, attacker, team, outcome ORDER BY iteration"
    ).fetchall()
    counts: dict[tuple[str, int], list[int]] = defaultdict(lambda: [0, 0])
    for iteration, attacker, team, outcome, n in rows:
        for pid, attacker_side in ((attacker, True), (team, False)):
            if pid in learners:
                entry = counts[(learners[pid].name, iteration)]
                entry[1] += n
                entry[0] += n if (outcome in ATTACKER_WINS) == attacker_side else 0
    series: dict[str, tuple[list, list]] = defaultdict(lambda: ([], []))
    for (name, iteration), (wins, games) in sorted(counts.items(), key=lambda kv: kv[0][1]):
        series[name][0].append(iteration)
        series[name][1].append(wins / games)
    return dict(series)


def trajectories(run: RunConfig, run_dir: Path, attacker: Player, team: Player, side: str, out_dir: Path) -> list[str]:
    """One won and one lost episode of ``side`` in ``attacker`` vs ``team``, as PNGs."""
    players = {**agents_of(attacker, run_dir), **agents_of(team, run_dir)}
    result = play(run.game, players, evaluation_scenarios(run.game.scenario, TRAJECTORY_GAMES), record=True)
    paths = np.stack(result.trajectory)  # (steps + 1, games, 3, 3)
    side_won = result.attacker_wins if side == "attacker" else ~result.attacker_wins
    files = []
    for label, mask in (("won", side_won), ("lost", ~side_won)):
        games = np.flatnonzero(mask)
        if not len(games):
            continue
        g = int(games[0])
        name = f"trajectory_{side}_{label}.png"
        steps = int(result.steps[g])
        plot_episode(paths[: steps + 1, g], Outcome(int(result.outcome[g])), run.game,
                     f"{attacker.name} vs {team.name} (game {g}): {side} {label}", out_dir / name)
        files.append(name)
    return files


def build_report(run_dir: Path) -> Path:
    run = saved_run_config(run_dir)
    store = LeagueStore(run_dir)
    out = run_dir / "report"
    out.mkdir(exist_ok=True)
    players = store.players()
    frozen = [p for p in players if p.kind != "learner"]
    attackers = [p for p in frozen if p.side == "attacker"]
    teams = [p for p in frozen if p.side == "team"]
    payoff = evaluation_payoff(store, run, run_dir, [(a, t) for a in attackers for t in teams])

    heat_map(payoff, attackers, teams, out / "payoff.png")
    ratings = defaultdict(lambda: ([], []))
    names = {p.id: p.name for p in players}
    for iteration, pid, rating in store.db.execute("SELECT iteration, player, rating FROM ratings ORDER BY iteration"):
        ratings[names[pid]][0].append(iteration)
        ratings[names[pid]][1].append(rating)
    line_plot(dict(ratings), "Elo rating", "ratings over training", out / "ratings.png")
    line_plot(learner_win_rates(store, players), "win rate in training", "learner win rates", out / "win_rates.png")
    returns = defaultdict(lambda: ([], []))
    for iteration, data in store.db.execute("SELECT iteration, returns FROM iterations ORDER BY iteration"):
        for module, value in json.loads(data or "{}").items():
            returns[module][0].append(iteration)
            returns[module][1].append(value)
    line_plot(dict(returns), "mean episode return", "episode returns of the learners", out / "returns.png")

    figures = []
    paper_team = next((t for t in teams if t.kind == "scripted"), None)
    scripted_attacker = next((a for a in attackers if a.kind == "scripted"), None)
    newest_attacker = [a for a in attackers if a.kind == "snapshot"][-1:]
    newest_team = [t for t in teams if t.kind == "snapshot"][-1:]
    if newest_attacker and paper_team:
        figures += trajectories(run, run_dir, newest_attacker[0], paper_team, "attacker", out)
    if newest_team and scripted_attacker:
        figures += trajectories(run, run_dir, scripted_attacker, newest_team[0], "team", out)

    last = store.last_iteration() or {}
    wall = store.db.execute("SELECT COALESCE(SUM(wall_seconds), 0) FROM iterations").fetchone()[0]
    text = [
        f"# Report: {run.name}",
        "",
        f"{last.get('iteration', 0)} iterations, {last.get('env_steps', 0)} env steps, {last.get('episodes', 0)} "
        f"training episodes, {wall:.0f} s of training iterations; {len(players)} players. Evaluation: "
        f"{run.evaluation.episodes} fixed games of scenario set `{run.game.scenario}` per pair.",
        "",
        "## Table 1 analogue",
        "",
        "The newest attacker snapshot of each reward method against the paper's training opponent "
        "(T to the terminal while avoiding A, D pursuing A). The paper's starting positions are not "
        "published, so compare the ordering, not the values.",
        "",
        table_one(store, payoff, players),
        "## Payoff matrix", "", "![payoff](payoff.png)", "",
        "## Ratings over training", "", "![ratings](ratings.png)", "",
        "## Learner win rates in training", "", "![win rates](win_rates.png)", "",
        "## Episode returns", "", "![returns](returns.png)", "",
        "## Trajectories", "",
    ]
    text += [f"![{name}]({name})" for name in figures]
    report = out / "report.md"
    report.write_text("\n".join(text) + "\n")
    store.close()
    return report


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m league.report", description=__doc__.splitlines()[0])
    parser.add_argument("--run-dir", type=Path, required=True)
    args = parser.parse_args(argv)
    try:
        open_run(args.run_dir)[1].close()  # checks config.yaml and league.db, one line if damaged
    except RunDirError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"report written to {build_report(args.run_dir.resolve())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

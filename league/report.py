"""A run's report: ``python -m league.report --run-dir DIR`` writes ``DIR/report/``.

* ``report.md`` with PNGs: the Table 1 analogue next to the paper's numbers, the payoff
  matrix and its meta-game (Nash mixtures and value, ``league.analysis.nash``), every snapshot against
  the scripted players of the other side by version (``league.analysis.generations``), the exploitability of
  the players ``league.exploit`` trained best responses against, ratings over training (one panel per side) and a table of every player's
  Elo and Nash-averaged rating, learner win rates and episode returns in the iterations their side learned
  (phases shaded; a line breaks between a learner's phases), and 3D trajectories of a won and a lost game
  for each side (the analogues of the paper's Fig. 3 and Fig. 4), and the learning curves
  (``league.curves``: win rate and return over env steps, with reference lines).
* ``index.html``: the same content in one self-contained file (plotly's JavaScript
  inside, so it opens offline), with the trajectories as 3D scenes to rotate, zoom and
  step through (``league.reports.html``).

Evaluation numbers are each pair's newest evaluation in the league database (a pair
played again on the same fixed games is one measurement, not more evidence); a pair the
run never evaluated is played now on the fixed evaluation games.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from dataclasses import dataclass, field
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
from league.curves import Curve, plot_run, read_curves
from league.analysis.exploitability import EXPLOITABILITY_HEADER, EXPLOITABILITY_NOTE, Exploitability, exploitability
from league.analysis.generations import GenerationLine, generation_lines, generations_plot
from league.evaluation.engine import agents_of, evaluate_pairs
from league.analysis.nash import MetaGame, format_meta_game, meta_game, meta_game_players
from league.analysis.statistics import wilson_interval
from league.core.payoff import aggregate, league_ratings, wins_of
from league.core.players import POOL_KINDS, Player
from league.state.run_dir import RunDirError, open_run
from league.state.store import LeagueStore

# The paper's Table 1: A's winning percentage over 100 test rounds per method.
PAPER_TABLE_1 = {1: 0.48, 2: 0.6253, 3: 0.5763}
TRAJECTORY_GAMES = 200
SIDE_COLOURS = {"attacker": "#d62728", "team": "#1f77b4"}  # phase shading and the sides' panels
DPI = 110

Series = dict[str, tuple[list[int], list[float]]]  # label -> (iterations, values)


@dataclass(frozen=True)
class Phase:
    index: int
    side: str
    first_iteration: int
    last_iteration: int


@dataclass(frozen=True)
class Episode:
    """One recorded game shown as a trajectory: ``side`` won or lost it."""

    side: str
    label: str  # "won" or "lost"
    pairing: str  # "ATTACKER vs TEAM (game G)"
    path: np.ndarray  # (steps + 1, 3 agents, 3) positions
    outcome: Outcome


@dataclass
class ReportData:
    run: RunConfig
    players: list[Player]
    attackers: list[Player]  # frozen, rows of the payoff matrix
    teams: list[Player]  # frozen, columns
    payoff: dict[tuple[int, int], tuple[int, int]]  # (attacker id, team id) -> (attacker wins, games)
    ratings: dict[int, tuple[list[int], list[float]]]  # player id -> (iterations, ratings) over training
    final_ratings: dict[int, float]  # fitted now to every game counted once; players without games have none
    games: dict[int, int]  # player id -> games in training and newest evaluations
    win_rates: Series
    returns: Series
    phases: list[Phase]
    episodes: list[Episode]
    missing_episodes: list[str]  # why a won or lost game of a side is not shown
    summary: str
    meta: MetaGame | None = None  # the Nash equilibrium of the payoff matrix (None: a side has no frozen player)
    exploitability: list[Exploitability] = field(default_factory=list)  # best responses of league.exploit
    generations: list[GenerationLine] = field(default_factory=list)  # snapshots against the scripted panel
    missing_generations: list[str] = field(default_factory=list)  # points of those lines not evaluated
    evaluated_iteration: int | None = None  # the run's final evaluation, whose games refit that iteration's ratings
    curves: list[Curve] = field(default_factory=list)  # learners on the fixed games as they trained (league.curves)


# ---------------------------------------------------------------- data
def evaluation_payoff(store: LeagueStore, run: RunConfig, run_dir: Path, needed: list[tuple[Player, Player]]):
    """``{(attacker id, team id): (attacker wins, games)}`` of each pair's newest evaluation, filling gaps."""
    table = aggregate(store.newest_evaluation_rows())
    missing = [(a, t) for a, t in needed if (a.id, t.id) not in table]
    for r in evaluate_pairs(run.game, run_dir, missing, run.evaluation.episodes):
        table[(r.attacker.id, r.team.id)] = (r.attacker_wins, r.games)
    return table


def player_games(store: LeagueStore, payoff: dict[tuple[int, int], tuple[int, int]]) -> dict[int, int]:
    """Games per player: training episodes plus the newest evaluation of each pair (gaps filled now)."""
    games: dict[int, int] = defaultdict(int)
    for table in (aggregate(store.outcome_rows("training")), payoff):
        for (attacker, team), (_, n) in table.items():
            games[attacker] += n
            games[team] += n
    return dict(games)


def learner_win_rates(store: LeagueStore, players: list[Player]) -> Series:
    """Each learner's win rate over its training episodes, per iteration it played."""
    learners = {p.id: p for p in players if p.trains}
    counts: dict[tuple[str, int], list[int]] = defaultdict(lambda: [0, 0])
    for iteration, row in store.training_rows_by_iteration():
        for pid in (row.attacker, row.team):
            if pid in learners:
                entry = counts[(learners[pid].name, iteration)]
                entry[1] += row.count
                entry[0] += row.wins(learners[pid].side)
    series: Series = defaultdict(lambda: ([], []))
    for (name, iteration), (wins, games) in sorted(counts.items(), key=lambda kv: kv[0][1]):
        series[name][0].append(iteration)
        series[name][1].append(wins / games)
    return dict(series)


def while_learning(series: Series, learner_sides: dict[str, str], learning_side: dict[int, str]) -> Series:
    """Each learner's points of the iterations in which its side learned. Episodes begun
    before a phase change finish in the next phase's first iteration: a handful, too few
    to plot as a learner's win rate or return."""
    kept: Series = {}
    for name, (x, y) in series.items():
        points = [(i, v) for i, v in zip(x, y) if learning_side.get(i) == learner_sides.get(name)]
        kept[name] = ([i for i, _ in points], [v for _, v in points])
    return kept


def phases_of(iterations: list[dict]) -> list[Phase]:
    phases: list[Phase] = []
    for row in iterations:
        if phases and phases[-1].index == row["phase"]:
            phases[-1] = Phase(row["phase"], row["learner_side"], phases[-1].first_iteration, row["iteration"])
        else:
            phases.append(Phase(row["phase"], row["learner_side"], row["iteration"], row["iteration"]))
    return phases


def record_episodes(run: RunConfig, run_dir: Path, attacker: Player, team: Player, side: str) -> tuple[list[Episode], list[str]]:
    """The first won and the first lost game of ``side`` in ``attacker`` vs ``team``; or why there is none."""
    players = {**agents_of(attacker, run_dir), **agents_of(team, run_dir)}
    result = play(run.game, players, evaluation_scenarios(run.game.scenario, TRAJECTORY_GAMES), record=True)
    paths = np.stack(result.trajectory)  # (steps + 1, games, 3, 3)
    side_won = wins_of(side, result.attacker_wins.astype(int), 1) == 1
    learned = attacker if side == "attacker" else team
    episodes, missing = [], []
    for label, mask in (("won", side_won), ("lost", ~side_won)):
        games = np.flatnonzero(mask)
        if not len(games):
            missing.append(f"{learned.name} ({side}) {'never won' if label == 'won' else 'never lost'} "
                           f"in {TRAJECTORY_GAMES} fixed games of {attacker.name} vs {team.name}.")
            continue
        g = int(games[0])
        pairing = f"{attacker.name} vs {team.name} (game {g})"
        episodes.append(Episode(side, label, pairing, paths[: int(result.steps[g]) + 1, g], Outcome(int(result.outcome[g]))))
    return episodes, missing


def gather(store: LeagueStore, run: RunConfig, run_dir: Path) -> ReportData:
    players = store.players()
    attackers, teams = meta_game_players(players)  # snapshots and scripted players
    payoff = evaluation_payoff(store, run, run_dir, [(a, t) for a in attackers for t in teams])

    ratings: dict[int, tuple[list[int], list[float]]] = defaultdict(lambda: ([], []))
    for iteration, pid, rating in store.rating_history():
        ratings[pid][0].append(iteration)
        ratings[pid][1].append(rating)
    returns: Series = defaultdict(lambda: ([], []))
    iterations = store.iteration_rows()
    for row in iterations:
        for module, value in json.loads(row["returns"] or "{}").items():
            returns[module][0].append(row["iteration"])
            returns[module][1].append(value)
    learner_sides = {p.name: p.side for p in players if p.trains}
    learning_side = {row["iteration"]: row["learner_side"] for row in iterations}

    # Each side's newest snapshot against a scripted opponent (the paper's team when there is one).
    scripted_teams = [t for t in teams if t.kind == "scripted"]
    paper_team = next((t for t in scripted_teams if t.is_paper_team),
                      scripted_teams[0] if scripted_teams else None)
    scripted_attacker = next((a for a in attackers if a.kind == "scripted"), None)
    newest_attacker = next((a for a in reversed(attackers) if a.kind == "snapshot"), None)
    newest_team = next((t for t in reversed(teams) if t.kind == "snapshot"), None)
    episodes, missing = [], []
    for side, attacker, team in (("attacker", newest_attacker, paper_team), ("team", scripted_attacker, newest_team)):
        if attacker is None or team is None:
            missing.append(f"No {side} trajectories: the league has no {side} snapshot or no scripted opponent for it.")
            continue
        shown, why = record_episodes(run, run_dir, attacker, team, side)
        episodes += shown
        missing += why

    last = store.last_iteration() or {}
    summary = (
        f"{last.get('iteration', 0)} iterations, {last.get('env_steps', 0)} env steps, {last.get('episodes', 0)} "
        f"training episodes, {store.training_seconds():.0f} s of training iterations; {len(players)} players. "
        f"Evaluation: {run.evaluation.episodes} fixed games of scenario set `{run.game.scenario}` per pair."
    )
    generations, missing_generations = generation_lines(players, payoff)
    return ReportData(
        run=run, players=players, attackers=attackers, teams=teams, payoff=payoff, ratings=dict(ratings),
        final_ratings=league_ratings(store.counted_results(), [p.id for p in players]),
        games=player_games(store, payoff),
        win_rates=while_learning(learner_win_rates(store, players), learner_sides, learning_side),
        returns=while_learning(dict(returns), learner_sides, learning_side),
        phases=phases_of(iterations), episodes=episodes, missing_episodes=missing, summary=summary,
        meta=meta_game(attackers, teams, payoff),
        exploitability=exploitability(players, store.newest_evaluation_rows()),
        generations=generations, missing_generations=missing_generations,
        evaluated_iteration=store.get_meta("evaluated_iteration"),
        curves=read_curves(store),
    )


# ---------------------------------------------------------------- tables
def table_one_rows(data: ReportData) -> list[list[str]]:
    """The newest attacker snapshot of each reward method against the paper's scripted team."""
    team = next((p for p in data.teams if p.is_paper_team), None)
    latest = {p.reward_method: p for p in data.attackers if p.kind == "snapshot"}
    rows = []
    for method, attacker in sorted(latest.items()):
        wins, games = data.payoff.get((attacker.id, team.id), (0, 0)) if team else (0, 0)
        low, high = wilson_interval(wins, games)
        rate = f"{wins / games:.3f}" if games else "not evaluated"
        rows.append([str(method), attacker.name, rate, f"[{low:.3f}, {high:.3f}]", str(games), str(PAPER_TABLE_1[method])])
    return rows


TABLE_ONE_HEADER = ["method", "attacker", "win rate vs the paper's scripted team", "95% interval", "games",
                    "paper (100 rounds)"]
CURVES_NOTE = ("Each learner, as it was every `evaluation.curve_every_env_steps` of its env steps, against its curve "
               "opponents on the same fixed games (deterministic actions; `league.curves`), with the scripted players "
               "of its side and its untrained version 0 on those games as horizontal lines.")
NO_META_GAME = "the league has no frozen attacker or no frozen team."
RATINGS_HEADER = ["player", "side", "kind", "rating", "Nash-averaged rating", "games"]
RATINGS_NOTE = ("Every player's rating, fitted to every game counted once: the training episodes and each pair's "
                "newest evaluation (the same fixed games played again are one measurement). A player without "
                "games has no rating. Nash-averaged rating: the player's win rate against the other side's Nash "
                "mixture (frozen league players only).")


def rating_rows(data: ReportData) -> list[list[str]]:
    """Every player's rating fitted to every game counted once, best first; players without games have none."""
    newest = data.final_ratings
    by_rating = sorted(data.players, key=lambda p: (p.id not in newest, -newest.get(p.id, 0.0)))
    nash = data.meta.ratings() if data.meta else {}
    return [[p.name, p.side, p.kind, f"{newest[p.id]:.0f}" if p.id in newest else "no games",
             f"{nash[p.id]:.3f}" if p.id in nash else "", str(data.games.get(p.id, 0))]
            for p in by_rating]


GENERATIONS_NOTE = ("Every snapshot of each side against the scripted players of the other side, by snapshot version: "
                    "rising lines, the league improves; lines that rise against some opponents and fall against "
                    "others, or go up and down, it cycles.")
NO_EXPLOITABILITY = "No best responses yet: python -m league.exploit --run-dir DIR --player NAME trains them."


def exploitability_markdown(data: ReportData) -> str:
    if not data.exploitability:
        return NO_EXPLOITABILITY + "\n"
    return EXPLOITABILITY_NOTE + "\n\n" + markdown_table(EXPLOITABILITY_HEADER, [e.row() for e in data.exploitability])


def markdown_table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join("---" for _ in header) + " |"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------- PNG plots
def payoff_grid(data: ReportData) -> np.ndarray:
    grid = np.full((len(data.attackers), len(data.teams)), np.nan)
    for i, a in enumerate(data.attackers):
        for j, t in enumerate(data.teams):
            wins, games = data.payoff.get((a.id, t.id), (0, 0))
            if games:
                grid[i, j] = wins / games
    return grid


def heat_map(data: ReportData, out: Path) -> None:
    grid = payoff_grid(data)
    rows, columns = grid.shape
    # Room for the labels, the colour bar and the title however few players there are.
    fig, ax = plt.subplots(figsize=(max(6.5, 3.4 + 0.85 * columns), max(3.6, 2.2 + 0.35 * rows)), layout="constrained")
    cmap = plt.get_cmap("RdBu_r")  # red: the attacker wins, blue: the team wins, white: even
    image = ax.imshow(grid, cmap=cmap, vmin=0, vmax=1, aspect="auto")
    ax.set_xticks(range(columns), [t.name for t in data.teams], rotation=35, ha="right", fontsize=8)
    ax.set_yticks(range(rows), [a.name for a in data.attackers], fontsize=8)
    for i in range(rows):
        for j in range(columns):
            if not np.isnan(grid[i, j]):
                r, g, b, _ = cmap(grid[i, j])
                dark = 0.2126 * r + 0.7152 * g + 0.0722 * b < 0.5  # relative luminance of the cell
                ax.text(j, i, f"{grid[i, j]:.2f}", ha="center", va="center", fontsize=8,
                        color="white" if dark else "black")
    fig.colorbar(image, label="attacker win rate", fraction=0.05)
    ax.set_title("attacker win rate, newest evaluation of each pair")
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


def broken(x: list[int], y: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """The series with a NaN between iterations that are not consecutive, so the line breaks there."""
    x_out, y_out = [], []
    for i, (xi, yi) in enumerate(zip(x, y)):
        if i and xi - x[i - 1] > 1:
            x_out.append(np.nan)
            y_out.append(np.nan)
        x_out.append(xi)
        y_out.append(yi)
    return np.array(x_out, dtype=float), np.array(y_out, dtype=float)


def shade_phases(ax, phases: list[Phase]) -> None:
    for phase in phases:
        ax.axvspan(phase.first_iteration - 0.5, phase.last_iteration + 0.5, color=SIDE_COLOURS[phase.side],
                   alpha=0.07, lw=0)


def phase_legend_handles() -> list:
    from matplotlib.patches import Patch

    return [Patch(color=c, alpha=0.15, label=f"{side} phase") for side, c in SIDE_COLOURS.items()]


def line_plot(series: Series, phases: list[Phase], ylabel: str, title: str, out: Path) -> None:
    fig, ax = plt.subplots(figsize=(8, 4.2))
    shade_phases(ax, phases)
    colours = plt.get_cmap("tab10")
    for k, (label, (x, y)) in enumerate(sorted(series.items())):
        ax.plot(*broken(x, y), label=label, lw=1.2, marker="o", ms=2.5, color=colours(k % 10))
    ax.set_xlabel("iteration")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    handles, _ = ax.get_legend_handles_labels()
    ax.legend(handles=handles + phase_legend_handles(), fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.tight_layout()
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


def ratings_plot(data: ReportData, out: Path) -> None:
    fig = ratings_figure(data)
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


def ratings_figure(data: ReportData):
    """One panel per side: learners, exploiters and scripted players named, snapshots as thin grey lines (see the table)."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.5), sharey=True)
    colours = plt.get_cmap("tab10")
    for ax, side in zip(axes, ("attacker", "team")):
        shade_phases(ax, data.phases)
        named = 0
        for player in (p for p in data.players if p.side == side):
            x, y = data.ratings.get(player.id, ([], []))
            if not x:
                continue
            if player.kind in POOL_KINDS:
                ax.plot(*broken(x, y), color="grey", lw=0.6, alpha=0.6)
                continue
            # Markers too: a player rated once (a scripted player met only in the final evaluation) is one point.
            style = {"lw": 1.8, "marker": "o", "ms": 2.5} if player.trains else {"lw": 1.2, "ls": "--", "marker": "o", "ms": 2.5}
            ax.plot(*broken(x, y), label=f"{player.name} ({player.kind})", color=colours(named % 10), **style)
            named += 1
        ax.plot([], [], color="grey", lw=0.6, label="snapshots (table below)")
        if data.evaluated_iteration is not None:
            ax.axvline(data.evaluated_iteration, color="black", lw=0.8, ls=":",
                       label="final evaluation: ratings refitted with its games")
        ax.set_title(f"{side} side")
        ax.set_xlabel("iteration")
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2, frameon=False)
    axes[0].set_ylabel("Elo rating")
    fig.suptitle("ratings over training (fitted to every result so far)")
    fig.tight_layout()
    return fig


# ---------------------------------------------------------------- the report
def build_report(run_dir: Path) -> Path:
    from league.reports import html as report_html

    import torch

    run = saved_run_config(run_dir)
    torch.set_num_threads(run.resources.threads_for(1))  # the games played here run torch in this process
    out = run_dir / "report"
    out.mkdir(exist_ok=True)
    store = LeagueStore(run_dir)
    try:
        data = gather(store, run, run_dir)
        has_curves = plot_run(store, run, out / "curves.png")
    finally:
        store.close()
    heat_map(data, out / "payoff.png")
    ratings_plot(data, out / "ratings.png")
    generations_plot(data.generations, out / "generations.png", DPI)
    line_plot(data.win_rates, data.phases, "win rate in training", "learner win rates (per iteration)", out / "win_rates.png")
    line_plot(data.returns, data.phases, "mean episode return", "episode returns of the learners", out / "returns.png")
    figures = []
    for episode in data.episodes:
        name = f"trajectory_{episode.side}_{episode.label}.png"
        plot_episode(episode.path, episode.outcome, run.game, f"{episode.pairing}: {episode.side} {episode.label}", out / name)
        figures.append(name)

    text = [
        f"# Report: {run.name}", "", data.summary, "",
        "## Table 1 analogue", "",
        "The newest attacker snapshot of each reward method against the paper's training opponent "
        "(T to the terminal while avoiding A, D pursuing A). The paper's starting positions are not "
        "published, so compare the ordering, not the values.", "",
        markdown_table(TABLE_ONE_HEADER, table_one_rows(data)),
        "## Payoff matrix", "", "![payoff](payoff.png)", "",
        "## Meta-game", "", format_meta_game(data.meta, NO_META_GAME),
        "## Progress over generations", "", GENERATIONS_NOTE, "", "![generations](generations.png)", "",
        *data.missing_generations, "",
        "## Exploitability", "", exploitability_markdown(data),
        "## Ratings", "", "![ratings](ratings.png)", "",
        RATINGS_NOTE, "",
        markdown_table(RATINGS_HEADER, rating_rows(data)),
        "## Learner win rates in training", "", "![win rates](win_rates.png)", "",
        "## Episode returns", "", "![returns](returns.png)", "",
        "## Learning curves", "",
        CURVES_NOTE if has_curves else "No learning curves recorded (`evaluation.curve_every_env_steps` is 0, "
        "or no learner reached it).", "",
        "![learning curves](curves.png)" if has_curves else "", "",
        "## Trajectories", "",
    ]
    text += [f"![{name}]({name})" for name in figures]
    text += ["", *data.missing_episodes]
    (out / "report.md").write_text("\n".join(text) + "\n")
    report_html.write(data, out / "index.html")
    return out / "report.md"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m league.report", description=__doc__.splitlines()[0])
    parser.add_argument("--run-dir", type=Path, required=True)
    args = parser.parse_args(argv)
    try:
        open_run(args.run_dir)[1].close()  # checks config.yaml and league.db, one line if damaged
    except RunDirError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    report = build_report(args.run_dir.resolve())
    print(f"report written to {report} and {report.with_name('index.html')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

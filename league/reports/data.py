"""The report's data: what ``league.reports.markdown`` and ``league.reports.html`` show, read from the store.

Evaluation numbers are each pair's newest evaluation in the league database (a pair
played again on the same fixed games is one measurement, not more evidence). Reading
only: ``python -m league.report`` plays the pairs the run never evaluated, and the
recorded trajectories, before it gathers this.
"""

from __future__ import annotations

import json
from collections import defaultdict
from dataclasses import dataclass, field

import numpy as np

from league.analysis.exploitability import Exploitability, run_exploitability
from league.analysis.generations import GenerationLine, generation_lines
from league.analysis.nash import MetaGame, meta_game, meta_game_players
from league.analysis.statistics import wilson_interval
from league.config import RunConfig
from league.core.payoff import aggregate, league_ratings
from league.core.payoff import attacker_won_games
from league.core.players import Player
from league.evaluation.by_class import CLASS_NOTE, ClassRates, class_header, game_classes
from league.evaluation.results import game_outcomes
from league.evaluation.learning_curves import Curve, read_curves
from league.evaluation.trajectories import Episode, Trajectories
from league.state.store import LeagueStore

# The paper's Table 1: A's winning percentage over 100 test rounds per method.
PAPER_TABLE_1 = {1: 0.48, 2: 0.6253, 3: 0.5763}

Series = dict[str, tuple[list[int], list[float]]]  # label -> (iterations, values)


@dataclass(frozen=True)
class Phase:
    index: int
    side: str
    first_iteration: int
    last_iteration: int


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
    curves: list[Curve] = field(default_factory=list)  # learners on the fixed games as they trained
    by_class: list[tuple[str, str, ClassRates]] = field(default_factory=list)  # (attacker, team, rates), a trained player in each
    classes: np.ndarray | None = None  # the start class of each dev game those rates count


def player_games(store: LeagueStore, payoff: dict[tuple[int, int], tuple[int, int]]) -> dict[int, int]:
    """Games per player: training episodes plus the newest evaluation of each pair."""
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


def gather(store: LeagueStore, run: RunConfig, trajectories: Trajectories | None = None) -> ReportData:
    """Everything the report shows, read from the store (``trajectories``: the games recorded for it, played by the caller)."""
    players = store.players()
    attackers, teams = meta_game_players(players)  # snapshots and scripted players
    payoff = aggregate(store.newest_evaluation_rows())
    trajectories = trajectories or Trajectories([], [])

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

    last = store.last_iteration() or {}
    summary = (
        f"{last.get('iteration', 0)} iterations, {last.get('env_steps', 0)} env steps, {last.get('episodes', 0)} "
        f"training episodes, {store.training_seconds():.0f} s of training iterations; {len(players)} players. "
        f"Evaluation: {run.evaluation.episodes} fixed dev games of scenario set `{run.game.scenario}` per pair."
    )
    generations, missing_generations = generation_lines(players, payoff)
    by_class, classes = class_rows(store, run, players)
    return ReportData(
        run=run, players=players, attackers=attackers, teams=teams, payoff=payoff, ratings=dict(ratings),
        final_ratings=league_ratings(store.counted_results(), [p.id for p in players]),
        games=player_games(store, payoff),
        win_rates=while_learning(learner_win_rates(store, players), learner_sides, learning_side),
        returns=while_learning(dict(returns), learner_sides, learning_side),
        phases=phases_of(iterations), episodes=trajectories.episodes, missing_episodes=trajectories.missing,
        summary=summary,
        meta=meta_game(attackers, teams, payoff),
        exploitability=run_exploitability(store),
        generations=generations, missing_generations=missing_generations,
        evaluated_iteration=store.get_meta("evaluated_iteration"),
        curves=read_curves(store), by_class=by_class, classes=classes,
    )


def class_rows(store: LeagueStore, run: RunConfig, players: list[Player]) -> tuple[list[tuple[str, str, ClassRates]], np.ndarray | None]:
    """Each evaluated pair with a trained player, its attacker win rate by start class on the dev
    games (``league.evaluation.by_class``), and the classes of those games (``None``: no outcomes stored)."""
    outcomes = game_outcomes(store, "dev")
    if not outcomes:
        return [], None
    by_id = {p.id: p for p in players}
    classes = game_classes(run.game, "dev", max(len(o) for o in outcomes.values()))
    rows = []
    for (attacker, team), games in sorted(outcomes.items()):
        pair = by_id.get(attacker), by_id.get(team)
        if None not in pair and any(p.kind != "scripted" for p in pair):
            rows.append((pair[0].name, pair[1].name, ClassRates.of(attacker_won_games(games), classes)))
    return rows, classes


def run_generations(store: LeagueStore) -> tuple[list[GenerationLine], list[str]]:
    """A run's progress over generations (``gather``'s), and the points not evaluated."""
    return generation_lines(store.players(), aggregate(store.newest_evaluation_rows()))


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
               "opponents on the same fixed dev games (deterministic actions; `league.evaluation.learning_curves`), with the scripted players "
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


CLASS_RATES_NOTE = CLASS_NOTE + " On the dev games of the run's evaluation, every evaluated pair with a trained player."
NO_CLASS_RATES = "No per-game outcomes of a pair with a trained player stored (python -m league.evaluate plays them)."


def class_rate_table(data: ReportData) -> tuple[list[str], list[list[str]]] | None:
    """Header and rows of the table by start class; ``None`` without rows."""
    if data.classes is None or not data.by_class:
        return None
    return ["attacker", "team", *class_header(data.classes)], [[a, t, *r.cells()] for a, t, r in data.by_class]


GENERATIONS_NOTE = ("Every snapshot of each side against the scripted players of the other side, by snapshot version "
                    "(an exploiter's snapshots are a lineage of their own, dashed): rising lines, the league improves; "
                    "lines that rise against some opponents and fall against others, or go up and down, it cycles.")
NO_EXPLOITABILITY = "No best responses yet: python -m league.exploit --run-dir DIR --player NAME trains them."


def payoff_grid(data: ReportData) -> np.ndarray:
    grid = np.full((len(data.attackers), len(data.teams)), np.nan)
    for i, a in enumerate(data.attackers):
        for j, t in enumerate(data.teams):
            wins, games = data.payoff.get((a.id, t.id), (0, 0))
            if games:
                grid[i, j] = wins / games
    return grid

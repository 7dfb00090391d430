"""Evaluation results into the store: each pair's newest evaluation, and the ratings refitted with it.

The evaluation engine only plays; what it played is recorded here by whoever asked
(the coordinator, ``league.evaluate``, ``league.exploit``, ``league.report``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from league.config import RunConfig
from league.core.payoff import aggregate, league_ratings
from league.core.players import Player
from league.evaluation.engine import PairEvaluation, evaluate_pairs
from league.evaluation.learning_curves import GameStats
from league.state.store import LeagueStore


# The store's ``matches.source`` of evaluations on each set of fixed games.
EVALUATION_SOURCE = {"dev": "evaluation", "test": "test"}


def record_evaluations(store: LeagueStore, iteration: int, results: list[PairEvaluation], games: str = "dev") -> None:
    """Record ``results``, played on the fixed ``games``, as evaluations of ``iteration``
    (inside the caller's transaction); on the dev games, refit that iteration's ratings too
    (the league's ratings never see the test games)."""
    for r in results:
        store.record_evaluation(iteration, r.outcome_rows(), EVALUATION_SOURCE[games])
        store.record_evaluation_stats(iteration, EVALUATION_SOURCE[games], r.attacker.id, r.team.id,
                                      GameStats.of(r.result).columns(), r.result.outcome.astype(np.uint8).tobytes())
    if games == "dev":
        store.replace_ratings(iteration, league_ratings(store.counted_results(), [p.id for p in store.players()]))


def last_iteration(store: LeagueStore) -> int:
    """The run's last recorded iteration (0 before the first): what evaluations are recorded under."""
    last = store.last_iteration()
    return last["iteration"] if last else 0


def evaluate_missing(
    store: LeagueStore, run: RunConfig, run_dir: Path, pairs: list[tuple[Player, Player]]
) -> list[PairEvaluation]:
    """Play the ``(attacker, team)`` pairs the store has no evaluation of on the run's fixed
    games, in this process, and record them; returns what was played."""
    evaluated = aggregate(store.newest_evaluation_rows())
    missing = [(a, t) for a, t in pairs if (a.id, t.id) not in evaluated]
    if not missing:
        return []
    results = evaluate_pairs(run.game, run_dir, missing, run.evaluation.episodes)
    with store.transaction():
        record_evaluations(store, last_iteration(store), results)
    return results


def test_game_stats(
    store: LeagueStore, run: RunConfig, run_dir: Path, pairs: list[tuple[Player, Player]], episodes: int, workers: int = 0
) -> dict[tuple[int, int], GameStats]:
    """Every pair's results on the first ``episodes`` held-out test games, by ``(attacker id, team id)``:
    the pairs not yet recorded with that many games are played (in this process, or on
    ``workers`` Ray actors) and recorded first."""
    recorded, outcomes = store.evaluation_stats("test"), store.evaluation_outcomes("test")
    missing = [(a, t) for a, t in pairs
               if recorded.get((a.id, t.id), {}).get("games") != episodes or (a.id, t.id) not in outcomes]
    if missing:
        results = evaluate_pairs(run.game, run_dir, missing, episodes, workers, games="test")
        with store.transaction():
            record_evaluations(store, last_iteration(store), results, "test")
        recorded = store.evaluation_stats("test")
    return {pair: GameStats.from_row(row) for pair, row in recorded.items()}


def game_outcomes(store: LeagueStore, games: str = "dev") -> dict[tuple[int, int], np.ndarray]:
    """Each pair's per-game ``Outcome`` values of its newest evaluation on the fixed ``games``, in game order."""
    return {pair: np.frombuffer(blob, dtype=np.uint8) for pair, blob in store.evaluation_outcomes(EVALUATION_SOURCE[games]).items()}


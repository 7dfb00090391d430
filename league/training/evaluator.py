"""A training run's evaluations on the fixed games: pairs during training, the whole league at the end.

The evaluation workers start at the first evaluation and serve every later one, the final
evaluation's too (``close`` stops them).
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path
from typing import Any, Callable

from league.config import RunConfig
from league.core.players import Player
from league.evaluation.engine import EvaluationPool, PairEvaluation, Workers, evaluate_pairs
from league.evaluation.results import record_evaluations
from league.evaluation.tables import evaluation_markdown
from league.state.run_dir import EVALUATION_FILE, write_replacing
from league.state.store import LeagueStore
from league.training.checkpoints import save_player
from league.training.stop import StopRequests


class Evaluator:
    def __init__(self, run: RunConfig, run_dir: Path, log: Callable[[str], None]):
        self.run = run
        self.run_dir = run_dir
        self.log = log
        self.pool: EvaluationPool | None = None  # made at the first evaluation

    def evaluate(self, pairs: list[tuple[Player, Player]]) -> list[PairEvaluation]:
        """``(attacker, team)`` pairs on the fixed games, by the evaluation workers (started at the first call)."""
        ev = self.run.evaluation
        if self.pool is None and ev.workers > 0:
            self.pool = EvaluationPool(
                self.run.game, self.run_dir, ev.workers, ev.cpus_per_worker, ev.custom_resources_per_worker, self.log,
                torch_threads=self.run.resources.torch_threads,
            )
        return evaluate_pairs(self.run.game, self.run_dir, pairs, ev.episodes, pool=self.pool)

    def learners_now(self, algo: Any, side: str, learners: list[Player], opponents: list[Player]) -> list[PairEvaluation]:
        """The ``side`` learners, as they are now (saved to ``players/NAME``), against ``opponents``."""
        pairs = []
        for learner in learners:
            current = replace(learner, checkpoint=save_player(algo, self.run_dir, learner.name, learner.name))
            for opponent in opponents:
                pairs.append((current, opponent) if side == "attacker" else (opponent, current))
        return self.evaluate(pairs)

    def league(self, store: LeagueStore, iteration: int, stop: StopRequests) -> tuple[list[PairEvaluation], Path, float]:
        """Every frozen attacker against every frozen team on the fixed evaluation games: recorded
        with refitted ratings as ``iteration``'s, written to ``evaluation.md``; with the seconds it played."""
        frozen = [p for p in store.players() if not p.trains]
        attackers = [p for p in frozen if p.side == "attacker"]
        teams = [p for p in frozen if p.side == "team"]
        pairs = [(attacker, team) for attacker in attackers for team in teams]
        ev, run = self.run.evaluation, self.run
        started = time.perf_counter()
        with stop.interruptible():  # playing the games writes nothing
            workers = Workers(ev.workers, ev.cpus_per_worker, ev.custom_resources_per_worker, run.resources.torch_threads)
            results = evaluate_pairs(run.game, self.run_dir, pairs, ev.episodes, workers, self.pool)
        seconds = time.perf_counter() - started
        with store.transaction():
            record_evaluations(store, iteration, results)
            store.set_meta("evaluated_iteration", iteration)
        out = self.run_dir / EVALUATION_FILE
        write_replacing(out, evaluation_markdown(run, iteration, results))
        return results, out, seconds

    def close(self) -> None:
        if self.pool is not None:
            self.pool.close()


"""The paper's Table 1 reproduced (``python -m league.reproduce``): the runs per reward variant,
budget, attacker reward method and seed, and the table of their evaluations."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from league.analysis.statistics import SEED_INTERVAL, mean_interval
from league.evaluation.results import test_game_stats
from league.reports.data import PAPER_TABLE_1
from league.state.run_dir import open_run
from league.studies.trials import TrainingRun


def attacker_win_rate(run_dir: Path, method: int, episodes: int) -> tuple[float, int]:
    """Win rate of ``attacker-m{method}-v1`` against the paper's scripted team on the first
    ``episodes`` held-out test games (played and recorded the first time)."""
    run, store = open_run(run_dir)
    try:
        attacker = next(
            p for p in store.players(side="attacker", kind="snapshot") if p.reward_method == method and p.version == 1
        )
        team = next(p for p in store.players(side="team", kind="scripted") if p.is_paper_team)
        stats = test_game_stats(store, run, run_dir, [(attacker, team)], episodes)[(attacker.id, team.id)]
    finally:
        store.close()
    return stats.win_rate("attacker"), stats.games


@dataclass(frozen=True)
class Budget:
    """A phase budget: ``kind`` is ``episodes`` or ``env_steps``."""

    kind: str
    amount: int

    @property
    def label(self) -> str:
        return f"{self.kind.replace('_', '-')}-{self.amount}"

    def describe(self) -> str:
        return f"{self.amount:,} {self.kind.replace('_', ' ')}"


@dataclass(frozen=True)
class Job:
    variant: str
    budget: Budget
    method: int
    seed: int
    run_dir: Path
    overrides: tuple[str, ...]


def phases_override(budget: Budget, team: bool) -> str:
    phases = [f"{{learner: attacker, {budget.kind}: {budget.amount}}}"]
    if team:
        phases.append(f"{{learner: team, {budget.kind}: {budget.amount}, opponents: latest}}")
    return f"league.phases=[{', '.join(phases)}]"


def training_run(job: Job, log: Path) -> TrainingRun:
    """``job`` as a study's run (``league.studies.trials``), its output in ``log``."""
    label = f"{job.variant}, {job.budget.describe()}, method {job.method}, seed {job.seed}"
    return TrainingRun(f"attacker_method{job.method}_paper", job.run_dir, job.overrides, label, log)


def own_method_returns(run_dir: Path, method: int) -> tuple[float, float, str] | None:
    """From the learning curves against the paper's team: the attacker's return under its own
    method at the last point, and the best scripted attacker's on the same games (with the run's
    terminal reward); ``None`` when the run recorded no curve."""
    from league.evaluation.learning_curves import read_curves
    from league.state.run_dir import open_run

    run, store = open_run(run_dir)
    try:
        curves = read_curves(store)
    finally:
        store.close()
    paper_team = "scripted-avoid_attacker+pure_pursuit"
    curve = next((c for c in curves if c.learner.reward_method == method and c.opponent.name == paper_team), None)
    if curve is None:
        return None
    reward = run.game.terminal_reward
    scripted = [(stats.attacker_return(method, reward), name) for kind, name, stats in curve.references if kind == "scripted"]
    best, name = max(scripted)
    return curve.stats[-1].attacker_return(method, reward), best, f"{name.removeprefix('scripted-')}, {curve.stats[-1].games} games"


def table(args: argparse.Namespace, variant: str, budget: Budget, jobs: list[Job], wall: float) -> str:
    rates: dict[int, list[float]] = {}
    returns: dict[int, list[tuple[float, float, str]]] = {}
    for job in jobs:
        rate, games = attacker_win_rate(job.run_dir, job.method, args.evaluation_episodes)
        rates.setdefault(job.method, []).append(rate)
        curve = own_method_returns(job.run_dir, job.method)
        if curve is not None:
            returns.setdefault(job.method, []).append(curve)
    terminal = f"a terminal reward of +-{args.terminal_reward:g}" if variant == "terminal" else "the paper's rewards (no terminal reward)"
    lines = [
        f"# Table 1 analogue: {variant}, {budget.describe()}",
        "",
        f"Attacker win rate against the paper's scripted team (T to the terminal avoiding A, D pursuing A), "
        f"{args.evaluation_episodes} held-out test games per seed, {budget.describe()} of training per attacker, "
        f"{terminal}, {args.seeds} seeds; mean with its interval ({SEED_INTERVAL}). "
        f"Overrides: {args.overrides or 'none'}. Wall time of this invocation (finished runs reused): {wall:.0f} s.",
        "",
        f"| method | per seed | mean | {SEED_INTERVAL} | paper (100 rounds) | own-method return per seed "
        "(last curve point) | best scripted attacker's return |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    means = {}
    for method, values in rates.items():
        means[method] = float(np.mean(values))
        spread = "[{:.3f}, {:.3f}]".format(*mean_interval(values)) if len(values) > 1 else "(one seed)"
        per_seed = ", ".join(f"{v:.3f}" for v in values)
        own = ", ".join(f"{r:.2f}" for r, _, _ in returns.get(method, [])) or "no curves"
        best = returns[method][0] if returns.get(method) else None
        scripted = f"{best[1]:.2f} ({best[2]})" if best else ""
        lines.append(
            f"| {method} | {per_seed} | {means[method]:.3f} | {spread} | {PAPER_TABLE_1[method]} | {own} | {scripted} |"
        )
    order = " > ".join(f"method {m}" for m in sorted(means, key=lambda m: -means[m]))
    lines += ["", f"Ordering here: {order}. The paper's: method 2 > method 3 > method 1."]
    return "\n".join(lines) + "\n"

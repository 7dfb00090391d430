"""Evaluation results as Markdown: the pair table, the table per attacker reward method, and
``evaluation.md`` (the run's final evaluation, which the coordinator writes)."""

from __future__ import annotations

from envs.agents import Outcome
from league.analysis.statistics import wilson_interval
from league.config import RunConfig
from league.core.players import Player
from league.evaluation.engine import PairEvaluation


def format_table(results: list[PairEvaluation]) -> str:
    """Markdown table: attacker win rate with its 95% Wilson interval and the outcomes."""
    lines = [
        "| attacker | team | games | attacker wins | 95% interval | "
        + " | ".join(o.label for o in Outcome if o != Outcome.RUNNING)
        + " |",
        "| --- | --- | --- | --- | --- | " + " | ".join("---" for o in Outcome if o != Outcome.RUNNING) + " |",
    ]
    for r in results:
        low, high = wilson_interval(r.attacker_wins, r.games)
        counts = r.result.outcome_counts()
        lines.append(
            f"| {r.attacker.name} | {r.team.name} | {r.games} | {r.attacker_wins / r.games:.3f} | "
            f"[{low:.3f}, {high:.3f}] | " + " | ".join(str(counts[o.label]) for o in Outcome if o != Outcome.RUNNING) + " |"
        )
    return "\n".join(lines) + "\n"


def latest_by_method(players: list[Player]) -> dict[int, Player]:
    """The newest attacker snapshot of each reward method."""
    latest: dict[int, Player] = {}
    for p in players:
        if p.side == "attacker" and p.kind == "snapshot":
            latest[p.reward_method] = p
    return latest


def method_table(results: list[PairEvaluation]) -> str:
    """Per attacker reward method (its newest snapshot): win rate against each kind of team,
    with a 95% Wilson interval over the fixed starts (not over the games of a pooled column)."""
    attackers = latest_by_method([r.attacker for r in results])
    teams = sorted({r.team.id: r.team for r in results}.values(), key=lambda p: p.id)
    scripted = [t for t in teams if t.kind == "scripted"]
    trained = [t for t in teams if t.kind == "snapshot"][-1:]
    columns = [(t.name, [t]) for t in scripted + trained] + [("league pool", teams)]
    lines = [
        "| reward method | attacker | " + " | ".join(name for name, _ in columns) + " |",
        "| --- | --- | " + " | ".join("---" for _ in columns) + " |",
    ]
    for method, attacker in sorted(attackers.items()):
        cells = []
        for _, group in columns:
            ids = {t.id for t in group}
            chosen = [r for r in results if r.attacker.id == attacker.id and r.team.id in ids]
            wins, games = sum(r.attacker_wins for r in chosen), sum(r.games for r in chosen)
            if not games:
                cells.append("")
                continue
            # A column of k teams replays the same n fixed starts against each team: its k * n
            # games are not independent, so the interval counts the n distinct starts. Wilson on
            # (pooled rate * n, n) is conservative: the k outcomes of one start average to a value
            # in [0, 1] with mean p, whose variance is at most p (1 - p), that of one game.
            starts = max(r.games for r in chosen)
            low, high = wilson_interval(wins / games * starts, starts)
            cells.append(f"{wins / games:.3f} [{low:.3f}, {high:.3f}]")
        lines.append(f"| {method} | {attacker.name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def evaluation_markdown(run: RunConfig, iteration: int, results: list[PairEvaluation]) -> str:
    """``evaluation.md``: the whole frozen league on the fixed games after ``iteration``."""
    return (
        f"# Evaluation of {run.name} after iteration {iteration}\n\n"
        f"{run.evaluation.episodes} fixed dev games of scenario set `{run.game.scenario}` per pair; "
        "attacker win rate with its 95% Wilson interval.\n\n" + format_table(results)
        + "\n## Per attacker reward method\n\n" + method_table(results)
    )

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


def method_columns(results: list[PairEvaluation]) -> list[tuple[str, list[Player]]]:
    """The columns of the table per reward method: each scripted team, the newest team snapshot, the league pool."""
    teams = sorted({r.team.id: r.team for r in results}.values(), key=lambda p: p.id)
    scripted = [t for t in teams if t.kind == "scripted"]
    trained = [t for t in teams if t.kind == "snapshot"][-1:]
    return [(t.name, [t]) for t in scripted + trained] + [("league pool", teams)]


def method_rows(results: list[PairEvaluation]) -> list[dict]:
    """The table per attacker reward method as data: each method's newest attacker snapshot against
    each scripted team, the newest team snapshot and the whole league pool, with a 95% Wilson
    interval over the fixed starts (``starts``) of a column, not over the games of a pooled one."""
    attackers = latest_by_method([r.attacker for r in results])
    rows = []
    for method, attacker in sorted(attackers.items()):
        cells = []
        for name, group in method_columns(results):
            ids = {t.id for t in group}
            chosen = [r for r in results if r.attacker.id == attacker.id and r.team.id in ids]
            wins, games = sum(r.attacker_wins for r in chosen), sum(r.games for r in chosen)
            cell = {"against": name, "teams": [t.name for t in group], "games": games, "attacker_wins": wins,
                    "attacker_win_rate": None, "starts": 0, "interval_95": None}
            if games:
                # A column of k teams replays the same n fixed starts against each team: its k * n
                # games are not independent, so the interval counts the n distinct starts. Wilson on
                # (pooled rate * n, n) is conservative: the k outcomes of one start average to a value
                # in [0, 1] with mean p, whose variance is at most p (1 - p), that of one game.
                starts = max(r.games for r in chosen)
                cell.update(attacker_win_rate=wins / games, starts=starts,
                            interval_95=list(wilson_interval(wins / games * starts, starts)))
            cells.append(cell)
        rows.append({"reward_method": method, "attacker": attacker.name, "columns": cells})
    return rows


def method_table(results: list[PairEvaluation]) -> str:
    """``method_rows`` as Markdown."""
    names = [name for name, _ in method_columns(results)]
    lines = [
        "| reward method | attacker | " + " | ".join(names) + " |",
        "| --- | --- | " + " | ".join("---" for _ in names) + " |",
    ]
    for row in method_rows(results):
        cells = ["" if c["attacker_win_rate"] is None else "{:.3f} [{:.3f}, {:.3f}]".format(c["attacker_win_rate"], *c["interval_95"])
                 for c in row["columns"]]
        lines.append(f"| {row['reward_method']} | {row['attacker']} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def evaluation_markdown(run: RunConfig, iteration: int, results: list[PairEvaluation]) -> str:
    """``evaluation.md``: the whole frozen league on the fixed games after ``iteration``."""
    return (
        f"# Evaluation of {run.name} after iteration {iteration}\n\n"
        f"{run.evaluation.episodes} fixed dev games of scenario set `{run.game.scenario}` per pair; "
        "attacker win rate with its 95% Wilson interval.\n\n" + format_table(results)
        + "\n## Per attacker reward method\n\n" + method_table(results)
    )

"""The report as Markdown with PNGs: ``report/report.md`` and the figures beside it (``league.reports.plots``)."""

from __future__ import annotations

from pathlib import Path

from envs.render import plot_episode
from league.analysis.exploitability import CURVE_NOTE, EXPLOITABILITY_HEADER, EXPLOITABILITY_NOTE, exploitability_curves
from league.analysis.nash import format_meta_game
from league.reports.data import (
    CLASS_RATES_NOTE,
    CURVES_NOTE,
    GENERATIONS_NOTE,
    NO_CLASS_RATES,
    NO_EXPLOITABILITY,
    NO_META_GAME,
    RATINGS_HEADER,
    RATINGS_NOTE,
    TABLE_ONE_HEADER,
    ReportData,
    class_rate_table,
    rating_rows,
    table_one_rows,
)
from league.reports.plots import (
    DPI, exploitability_plot, generations_plot, heat_map, line_plot, plot_run_curves, ratings_plot,
)


def exploitability_markdown(data: ReportData, out: Path) -> str:
    if not data.exploitability:
        return NO_EXPLOITABILITY + "\n"
    text = EXPLOITABILITY_NOTE + "\n\n" + markdown_table(EXPLOITABILITY_HEADER, [e.row() for e in data.exploitability])
    curves = exploitability_curves(data.exploitability)
    if curves:
        exploitability_plot(curves, out / "exploitability.png")
        text += f"\n{CURVE_NOTE}\n\n![exploitability over the phases](exploitability.png)\n"
    return text


def class_section(data: ReportData) -> list[str]:
    table = class_rate_table(data)
    return [NO_CLASS_RATES, ""] if table is None else [CLASS_RATES_NOTE, "", markdown_table(*table)]


def markdown_table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join("---" for _ in header) + " |"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def write_markdown(data: ReportData, out: Path) -> Path:
    """``report.md`` and its PNGs in the directory ``out``; returns the Markdown file."""
    run = data.run
    heat_map(data, out / "payoff.png")
    ratings_plot(data, out / "ratings.png")
    generations_plot(data.generations, out / "generations.png", DPI)
    has_curves = plot_run_curves(data.curves, run, out / "curves.png")
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
        "## By start class", "", *class_section(data),
        "## Payoff matrix", "", "![payoff](payoff.png)", "",
        "## Meta-game", "", format_meta_game(data.meta, NO_META_GAME),
        "## Progress over generations", "", GENERATIONS_NOTE, "", "![generations](generations.png)", "",
        *data.missing_generations, "",
        "## Exploitability", "", exploitability_markdown(data, out),
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
    return out / "report.md"

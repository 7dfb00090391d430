"""Progress over generations: every snapshot of each side against a fixed panel, the scripted
players of the other side.

A league that improves shows each lineage's win rate rising with the snapshot version
against the whole panel; one that cycles shows it rising against some panel members and
falling against others, or going up and down. The numbers are each pair's newest
evaluation on the fixed games (``league.report`` plays a pair the run never evaluated
before it draws; a point still missing is named under the plot).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from league.analysis.statistics import wilson_interval
from league.core.payoff import record_against
from league.core.players import Player

SIDES = ("attacker", "team")
PANEL_TITLES = {"attacker": "attacker snapshots vs the scripted teams", "team": "team snapshots vs the scripted attackers"}


@dataclass(frozen=True)
class GenerationLine:
    """One lineage's snapshots (``attacker-m2``, ``team``) against one scripted opponent, by version."""

    side: str
    lineage: str
    opponent: str
    versions: list[int]
    wins: list[int]  # the snapshot's wins
    games: list[int]

    @property
    def label(self) -> str:
        return f"{self.lineage} vs {self.opponent}"

    @property
    def rates(self) -> list[float]:
        return [w / n for w, n in zip(self.wins, self.games)]

    @property
    def intervals(self) -> list[tuple[float, float]]:
        return [wilson_interval(w, n) for w, n in zip(self.wins, self.games)]

    def error_bars(self) -> tuple[list[float], list[float]]:
        """Distances from each rate down and up to its interval's ends; at 0 or 1 wins of all
        games the interval's end lands on the rate up to rounding (1 - 1e-16), not past it."""
        below = [max(0.0, r - low) for r, (low, _) in zip(self.rates, self.intervals)]
        above = [max(0.0, high - r) for r, (_, high) in zip(self.rates, self.intervals)]
        return below, above


def generation_lines(
    players: list[Player], payoff: dict[tuple[int, int], tuple[int, int]]
) -> tuple[list[GenerationLine], list[str]]:
    """The lines of both sides from ``{(attacker id, team id): (attacker wins, games)}``, and the missing points."""
    lines, missing = [], []
    for side in SIDES:
        snapshots = [p for p in players if p.side == side and p.kind == "snapshot"]
        panel = [p for p in players if p.side != side and p.kind == "scripted"]
        lineages = sorted({replace(s, kind="learner").name for s in snapshots})
        for lineage in lineages:
            members = sorted((s for s in snapshots if replace(s, kind="learner").name == lineage), key=lambda s: s.version)
            for opponent in panel:
                versions, wins, games = [], [], []
                for snapshot in members:
                    won, n = record_against(payoff, side, snapshot.id, opponent.id)
                    if not n:
                        missing.append(f"{snapshot.name} vs {opponent.name} not evaluated")
                        continue
                    versions.append(snapshot.version)
                    wins.append(won)
                    games.append(n)
                lines.append(GenerationLine(side, lineage, opponent.name, versions, wins, games))
    return lines, missing


def generations_plot(lines: list[GenerationLine], out: Path, dpi: int = 110) -> None:
    """One panel per side: win rate of each snapshot (95% Wilson interval) against each scripted opponent."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8), sharey=True)
    colours = plt.get_cmap("tab10")
    for ax, side in zip(axes, SIDES):
        shown = [line for line in lines if line.side == side]
        for k, line in enumerate(shown):
            ax.errorbar(line.versions, line.rates, yerr=list(line.error_bars()), label=line.label, marker="o", ms=3.5, lw=1.2,
                        capsize=2.5, color=colours(k % 10))
        if shown:
            ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), frameon=False)
        else:
            ax.text(0.5, 0.5, f"no {side} snapshot or no scripted opponent", ha="center", va="center", transform=ax.transAxes)
        ax.set_title(PANEL_TITLES[side])
        ax.set_xlabel("snapshot version")
        ax.set_ylim(-0.03, 1.03)
        ax.xaxis.get_major_locator().set_params(integer=True)
    axes[0].set_ylabel("win rate of the snapshot")
    fig.suptitle("progress over generations (newest evaluation of each pair, 95% Wilson intervals)")
    fig.tight_layout()
    fig.savefig(out, dpi=dpi)
    plt.close(fig)


def generations_figure(lines: list[GenerationLine]) -> go.Figure:
    """The same as ``generations_plot``, interactive."""
    fig = make_subplots(rows=1, cols=2, shared_yaxes=True, subplot_titles=[PANEL_TITLES[s] for s in SIDES])
    for column, side in enumerate(SIDES, start=1):
        for line in (line for line in lines if line.side == side):
            below, above = line.error_bars()
            fig.add_trace(go.Scatter(
                x=line.versions, y=line.rates, name=line.label, mode="lines+markers",
                error_y=dict(type="data", symmetric=False, array=above, arrayminus=below),
                customdata=list(zip(line.wins, line.games)),
                hovertemplate="version %{x}: %{y:.3f} (%{customdata[0]} of %{customdata[1]} games)",
            ), row=1, col=column)
        fig.update_xaxes(title_text="snapshot version", dtick=1, row=1, col=column)
    fig.update_yaxes(title_text="win rate of the snapshot", range=[-0.03, 1.03], row=1, col=1)
    fig.update_layout(title="progress over generations (newest evaluation of each pair, 95% Wilson intervals)", height=460)
    return fig

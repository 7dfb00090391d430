"""The report's PNG figures (matplotlib): payoff heat map, ratings, win rates and returns over
training, progress over generations, and learning curves (one run, or several runs' means).
``league.reports.html`` draws the same with plotly."""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from league.analysis.exploitability import CURVE_TITLE, Exploitability
from league.analysis.generations import PANEL_TITLES, SIDES, GenerationLine
from league.config import RunConfig
from league.core.players import POOL_KINDS, Player, other_side
from league.evaluation.learning_curves import Curve, GameStats, read_curves, scripted_references
from league.reports.data import Phase, ReportData, Series, payoff_grid

SIDE_COLOURS = {"attacker": "#d62728", "team": "#1f77b4"}  # phase shading and the sides' panels
DPI = 110
HEAT_MAP_CELL = 0.6  # inches a side of a payoff cell
HEAT_MAP_TITLE = "attacker win rate, newest evaluation of each pair"


# ---------------------------------------------------------------- league over training
def heat_map(data: ReportData, out: Path) -> None:
    fig = heat_map_figure(data)
    fig.savefig(out, dpi=DPI, bbox_inches="tight", pad_inches=0.1)  # every label whole, however long
    plt.close(fig)


def heat_map_figure(data: ReportData):
    grid = payoff_grid(data)
    rows, columns = grid.shape
    # Square cells, the figure sized from the matrix and its labels (8 pt: about 0.065 inch a
    # character; the teams' labels turned by 35 degrees), so that no shape of league is squashed.
    char = 0.065
    below = 0.5 + char * max(map(len, (t.name for t in data.teams)), default=0) * math.sin(math.radians(35))
    left = 0.3 + char * max(map(len, (a.name for a in data.attackers)), default=0)
    # At least the width of the title (12 pt, about 0.1 inch a character), which is centred on the figure.
    fig, ax = plt.subplots(
        figsize=(max(0.1 * len(HEAT_MAP_TITLE), left + HEAT_MAP_CELL * columns + 1.3), 0.5 + HEAT_MAP_CELL * rows + below),
        layout="constrained",
    )
    cmap = plt.get_cmap("RdBu_r")  # red: the attacker wins, blue: the team wins, white: even
    image = ax.imshow(grid, cmap=cmap, vmin=0, vmax=1, aspect="equal")
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
    fig.suptitle(HEAT_MAP_TITLE)
    return fig


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


def exploitability_plot(curves: dict[tuple[str, str, int], list[Exploitability]], out: Path) -> None:
    """``league.analysis.exploitability.exploitability_curves``: each mixture's best responses over the phases."""
    fig, ax = plt.subplots(figsize=(8, 4.2))
    for (side, games, budget), items in sorted(curves.items()):
        x = [e.exploited.iteration for e in items]
        low, high = np.array([e.bounds() for e in items]).T
        mean = np.array([e.mean for e in items])
        colour = SIDE_COLOURS[other_side(side)]
        ax.errorbar(x, mean, yerr=[mean - low, high - mean], color=colour, marker="o", capsize=3,
                    label=f"best responses against nash-{side}@K ({budget:,} env steps, {games} games)")
        members = [(k, e.baseline.member_rate) for k, e in zip(x, items) if e.baseline.member is not None]
        if members:
            ax.plot(*zip(*members), color=colour, ls="--", marker=".", label=f"best league {other_side(side)} at K")
    ax.set_xlabel("iteration K")
    ax.set_ylabel("win rate against the mixture")
    ax.set_ylim(0, 1)
    ax.set_title(CURVE_TITLE)
    ax.legend(fontsize=7)
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


# ---------------------------------------------------------------- generations
GENERATIONS_TITLE = "progress over generations (newest evaluation of each pair, 95% Wilson intervals)"


def generations_axis(ax, lines: list[GenerationLine], side: str, title: str) -> None:
    """One side's lines on one panel: learners' lineages solid, exploiters' dashed (their colours in the same order)."""
    shown = [line for line in lines if line.side == side]
    colours = plt.get_cmap("tab10")
    for kind in POOL_KINDS:
        for k, line in enumerate(line for line in shown if line.kind == kind):
            ax.errorbar(line.versions, line.rates, yerr=list(line.error_bars()), label=line.label,
                        marker="o" if kind == "snapshot" else "s", ms=3.5, lw=1.2, capsize=2.5, color=colours(k % 10),
                        ls="-" if kind == "snapshot" else "--")
    if shown:
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), frameon=False)
    else:
        ax.text(0.5, 0.5, f"no {side} snapshot or no scripted opponent", ha="center", va="center", transform=ax.transAxes)
    ax.set_title(title)
    ax.set_xlabel("snapshot version")
    ax.set_ylim(-0.03, 1.03)
    ax.xaxis.get_major_locator().set_params(integer=True)


def generations_plot(lines: list[GenerationLine], out: Path, dpi: int = 110) -> None:
    """One panel per side: win rate of each snapshot (95% Wilson interval) against each scripted opponent."""
    runs_generations_plot([("", lines)], out, dpi)


def runs_generations_plot(runs: list[tuple[str, list[GenerationLine]]], out: Path, dpi: int = 110) -> None:
    """``generations_plot`` of several runs (seeds of one config): a row of both sides' panels per run."""
    entries = max((sum(line.side == side for line in lines) for _, lines in runs for side in SIDES), default=0)
    height = 4.8 + 0.12 * max(0, entries - 3)  # a row's height: room for its legends, one entry per line
    fig, axes = plt.subplots(len(runs), 2, figsize=(12, height * len(runs)), sharey=True, squeeze=False)
    for row, (name, lines) in zip(axes, runs):
        for ax, side in zip(row, SIDES):
            generations_axis(ax, lines, side, f"{name}: {PANEL_TITLES[side]}" if name else PANEL_TITLES[side])
        row[0].set_ylabel("win rate of the snapshot")
    fig.suptitle(GENERATIONS_TITLE)
    fig.tight_layout()
    fig.savefig(out, dpi=dpi)
    plt.close(fig)


# ---------------------------------------------------------------- learning curves
@dataclass(frozen=True)
class Quantity:
    """One panel: a number per measurement, for a learner of ``side``."""

    title: str
    value: Callable[[GameStats, Player, float], float]  # (stats, learner, terminal reward)


WIN_RATE = Quantity("win rate", lambda s, learner, r: s.win_rate(learner.side))
OWN_RETURN = Quantity(
    "return under its own reward method", lambda s, learner, r: s.attacker_return(learner.reward_method, r)
)
TEAM_RETURN = Quantity("team return (T + D, Eq. 10 + 11)", lambda s, learner, r: s.team_return(r))


def quantities(learner: Player) -> list[Quantity]:
    return [WIN_RATE, OWN_RETURN] if learner.side == "attacker" else [WIN_RATE, TEAM_RETURN]


REFERENCE_STYLES = {"scripted": {"ls": "--", "lw": 1.0}, "untrained": {"ls": ":", "lw": 1.4}}
# One colour per reference, the same in every panel; the untrained player is black.
REFERENCE_COLOURS = ["#8c564b", "#9467bd", "#17becf", "#bcbd22", "#e377c2", "#ff7f0e", "#2ca02c"]


def reference_colour(kind: str, name: str) -> str:
    if kind == "untrained":
        return "black"
    names = [p.name for side in ("attacker", "team") for p in scripted_references(side)]
    return REFERENCE_COLOURS[names.index(name) % len(REFERENCE_COLOURS)] if name in names else "grey"


def _reference_lines(ax, references: list[tuple[str, str, float]]) -> None:
    """Horizontal lines labelled at the right edge; labels pushed apart so they stay readable."""
    ordered = sorted(references, key=lambda r: r[2])
    values = [r[2] for r in ordered]
    low, high = ax.get_ylim()
    low, high = min([low, *values]), max([high, *values])
    gap = (high - low) * 0.07
    placed: list[float] = []
    for kind, name, value in ordered:
        colour = reference_colour(kind, name)
        ax.axhline(value, color=colour, **REFERENCE_STYLES[kind])
        y = max(value, placed[-1] + gap) if placed else value
        placed.append(y)
        label = "untrained (v0)" if kind == "untrained" else name.removeprefix("scripted-")
        ax.annotate(f"{label} {value:.3g}", xy=(1.0, y), xycoords=("axes fraction", "data"), xytext=(4, 0),
                    textcoords="offset points", va="center", fontsize=7, color=colour)
    ax.set_ylim(low - gap, max(high, placed[-1] if placed else high) + gap)


def _win_band(ax, x: list[int], stats: list[GameStats], side: str, colour: str) -> None:
    bounds = np.array([s.win_interval(side) for s in stats])
    ax.fill_between(x, bounds[:, 0], bounds[:, 1], color=colour, alpha=0.15, lw=0, label="95% Wilson interval")


def plot_curves(groups: list[list[Curve]], terminal_reward: float, title: str, out: Path) -> None:
    """``curves_figure`` saved to ``out``."""
    fig = curves_figure(groups, terminal_reward, title)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def curves_figure(groups: list[list[Curve]], terminal_reward: float, title: str):
    """One row per (learner, opponent) group, one panel per quantity.

    A group holds the same curve of several runs (seeds): one thin line each and their
    mean; a group of one run is drawn as one line with its win-rate interval.
    References are drawn at their mean over the runs.
    """
    from matplotlib.ticker import EngFormatter, MaxNLocator

    rows, row_inches = len(groups), 3.4
    fig, axes = plt.subplots(rows, 2, figsize=(15, row_inches * rows), squeeze=False)
    for row, group in zip(axes, groups):
        learner, opponent = group[0].learner, group[0].opponent
        for ax, quantity in zip(row, quantities(learner)):
            lines = [(c.env_steps, [quantity.value(s, c.learner, terminal_reward) for s in c.stats]) for c in group]
            if len(group) == 1:
                x, y = lines[0]
                if quantity is WIN_RATE:
                    _win_band(ax, x, group[0].stats, learner.side, "#1f77b4")
                ax.plot(x, y, marker="o", ms=3, lw=1.5, color="#1f77b4", label=learner.name)
            else:
                for k, (x, y) in enumerate(lines):
                    ax.plot(x, y, lw=0.8, alpha=0.5, color="#1f77b4", label="each seed" if k == 0 else None)
                mean_x, mean_y = mean_curve(lines)
                ax.plot(mean_x, mean_y, lw=2.0, color="#d62728", label=f"mean of {len(group)} seeds")
            refs: dict[tuple[str, str], list[float]] = defaultdict(list)
            for curve in group:
                for kind, name, stats in curve.references:
                    refs[(kind, "untrained" if kind == "untrained" else name)].append(
                        quantity.value(stats, curve.learner, terminal_reward)
                    )
            _reference_lines(ax, [(kind, name, float(np.mean(v))) for (kind, name), v in sorted(refs.items())])
            ax.set_xlabel(f"env steps of {learner.name}")
            # At most 5 ticks, as "200k" and "1.2M": full env-step counts ran together.
            ax.xaxis.set_major_locator(MaxNLocator(nbins=5))
            ax.xaxis.set_major_formatter(EngFormatter(sep=""))
            ax.set_title(f"{learner.name} vs {opponent.name}: {quantity.title}", fontsize=9)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7, loc="best")
    note = f" (terminal reward {terminal_reward:g} included)" if terminal_reward else ""
    fig.suptitle(title + note, fontsize=10)
    # Room on the right of each panel for the reference labels (tight_layout ignores them).
    height = row_inches * rows
    fig.subplots_adjust(left=0.05, right=0.83, wspace=0.55, hspace=0.55, top=1 - 0.8 / height, bottom=0.5 / height)
    return fig


def mean_curve(lines: list[tuple[list[int], list[float]]]) -> tuple[np.ndarray, np.ndarray]:
    """Mean of several runs' curves, point by point over the points every run has (runs of one
    config measure at the same env steps, up to a batch); x is the mean of their env steps."""
    length = min(len(x) for x, _ in lines)
    x = np.mean([np.asarray(x[:length], dtype=float) for x, _ in lines], axis=0)
    y = np.mean([np.asarray(y[:length], dtype=float) for _, y in lines], axis=0)
    return x, y


def plot_run(store: Any, run: RunConfig, out: Path) -> bool:
    """Draw one run's curves into ``out``; False (and nothing drawn) when it recorded none."""
    return plot_run_curves(read_curves(store), run, out)


def plot_run_curves(curves: list[Curve], run: RunConfig, out: Path) -> bool:
    """``plot_run`` of curves already read."""
    if not curves:
        return False
    plot_curves([[c] for c in curves], run.game.terminal_reward, f"learning curves of {run.name}", out)
    return True

"""The report as one self-contained HTML page (``report/index.html``), built with plotly.

plotly's JavaScript is written into the page once, so it opens offline and can be mailed
as a single file. The trajectories are 3D scenes: drag to rotate, scroll to zoom, and
step through the game with the slider or the play button.
"""

from __future__ import annotations

import math
import html
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import plotly.graph_objects as go
from plotly.offline import get_plotlyjs
from plotly.subplots import make_subplots

from envs.agents import AGENTS, ATTACKER, DEFENDER, TARGETER, Outcome
from envs.render import COLOURS
from league.analysis.exploitability import (
    CURVE_NOTE, CURVE_TITLE, EXPLOITABILITY_HEADER, EXPLOITABILITY_NOTE, Exploitability, exploitability_curves,
)
from league.analysis.generations import PANEL_TITLES, SIDES, GenerationLine
from league.analysis.nash import GROUP_HEADER, GROUP_NOTE, GROUP_TITLE, META_GAME_NOTE, MIXTURE_HEADER, MIXTURE_TITLE
from league.core.players import POOL_KINDS, other_side
from league.evaluation.trajectories import Episode
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
    Phase,
    ReportData,
    Series,
    class_rate_table,
    payoff_grid,
    rating_rows,
    table_one_rows,
)
from league.reports.plots import GENERATIONS_TITLE, SIDE_COLOURS, quantities, reference_colour

if TYPE_CHECKING:
    from envs.config import GameConfig

# envs.render names matplotlib colours; the browser needs CSS ones.
CSS = {"tab:red": "#d62728", "tab:blue": "#1f77b4", "tab:green": "#2ca02c"}
AGENT_COLOURS = {agent: CSS.get(c, c) for agent, c in COLOURS.items()}
PAYOFF_CELL_PX = 44  # the height of a row of the payoff heat map
TEAM_LABEL_ANGLE = 35  # degrees the teams' names are turned under it
PAGE_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1200px; color: #222; }
table { border-collapse: collapse; margin: 1em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th { background: #f3f3f3; } td:first-child, th:first-child { text-align: left; }
.scenes { display: grid; grid-template-columns: 1fr 1fr; gap: 1em; }
.note { color: #555; }
"""


def html_table(header: list[str], rows: list[list[str]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def figure_div(fig: go.Figure, div_id: str) -> str:
    # auto_play off: an animated scene starts at the end of the game and plays on request.
    return fig.to_html(full_html=False, include_plotlyjs=False, div_id=div_id, auto_play=False,
                       config={"displaylogo": False})


def phase_shapes(phases: list[Phase]) -> list[dict]:
    return [
        dict(type="rect", xref="x", yref="paper", x0=p.first_iteration - 0.5, x1=p.last_iteration + 0.5, y0=0, y1=1,
             fillcolor=SIDE_COLOURS[p.side], opacity=0.07, line_width=0, layer="below")
        for p in phases
    ]


def broken_lists(x: list[int], y: list[float]) -> tuple[list, list]:
    """``None`` between non-consecutive iterations: plotly breaks the line there."""
    xs, ys = [], []
    for i, (xi, yi) in enumerate(zip(x, y)):
        if i and xi - x[i - 1] > 1:
            xs.append(None)
            ys.append(None)
        xs.append(xi)
        ys.append(yi)
    return xs, ys


def line_figure(series: Series, phases: list[Phase], ylabel: str, title: str) -> go.Figure:
    fig = go.Figure()
    for label, (x, y) in sorted(series.items()):
        xs, ys = broken_lists(x, y)
        fig.add_trace(go.Scatter(x=xs, y=ys, name=label, mode="lines+markers", marker_size=4))
    fig.update_layout(title=title, xaxis_title="iteration", yaxis_title=ylabel, shapes=phase_shapes(phases),
                      height=420, legend_title_text="shaded: red attacker phase, blue team phase")
    return fig


def ratings_figure(data: ReportData) -> go.Figure:
    fig = make_subplots(rows=1, cols=2, shared_yaxes=True, subplot_titles=("attacker side", "team side"))
    for col, side in enumerate(("attacker", "team"), start=1):
        for player in (p for p in data.players if p.side == side):
            x, y = data.ratings.get(player.id, ([], []))
            if not x:
                continue
            xs, ys = broken_lists(x, y)
            snapshot = player.kind in POOL_KINDS
            fig.add_trace(go.Scatter(
                x=xs, y=ys, name=player.name, mode="lines", legendgroup=side,
                line=dict(width=0.8 if snapshot else 2, dash="dash" if player.kind == "scripted" else "solid"),
                opacity=0.5 if snapshot else 1.0, visible="legendonly" if snapshot else True,
            ), row=1, col=col)
    fig.update_layout(title="ratings over training (snapshots hidden: click them in the legend)", height=460,
                      yaxis_title="Elo rating")
    fig.update_xaxes(title_text="iteration")
    return fig


def payoff_figure(data: ReportData) -> go.Figure:
    grid = payoff_grid(data)
    text = np.where(np.isnan(grid), "", np.vectorize(lambda v: f"{v:.2f}")(np.nan_to_num(grid)))
    fig = go.Figure(go.Heatmap(
        z=grid, x=[t.name for t in data.teams], y=[a.name for a in data.attackers], zmin=0, zmax=1,
        colorscale="RdBu_r", text=text, texttemplate="%{text}", colorbar_title="attacker<br>win rate",
        hovertemplate="%{y} vs %{x}: %{z:.3f}<extra></extra>",
    ))
    # Sized from the matrix: rows of PAYOFF_CELL_PX, room below for the teams' names at TEAM_LABEL_ANGLE
    # (about 7 px a character) and above for the title; square cells (``scaleanchor``) however wide the page.
    rows, longest = len(data.attackers), max((len(t.name) for t in data.teams), default=0)
    below = 40 + 7 * longest * math.sin(math.radians(TEAM_LABEL_ANGLE))
    fig.update_layout(title="attacker win rate, newest evaluation of each pair", height=round(90 + PAYOFF_CELL_PX * rows + below),
                      yaxis_autorange="reversed", yaxis_scaleanchor="x", yaxis_constrain="domain",
                      xaxis_tickangle=-TEAM_LABEL_ANGLE, xaxis_constrain="domain")
    return fig


def sphere(radius: float) -> go.Surface:
    u, v = np.mgrid[0 : 2 * np.pi : 24j, 0 : np.pi : 12j]
    return go.Surface(x=radius * np.cos(u) * np.sin(v), y=radius * np.sin(u) * np.sin(v), z=radius * np.cos(v),
                      showscale=False, opacity=0.25, colorscale=[[0, "grey"], [1, "grey"]], name="terminal sphere",
                      showlegend=True, hoverinfo="skip")


def trajectory_figure(episode: Episode, game: "GameConfig") -> go.Figure:
    """The game as a 3D scene; the frames step through it, one env step each."""
    path = episode.path
    steps = len(path) - 1
    agents = (ATTACKER, TARGETER, DEFENDER)

    def moving(k: int) -> list[go.Scatter3d]:
        traces = []
        for agent in agents:
            p = path[: k + 1, agent]
            traces.append(go.Scatter3d(x=p[:, 0], y=p[:, 1], z=p[:, 2], mode="lines", name=AGENTS[agent],
                                       line=dict(color=AGENT_COLOURS[agent], width=5)))
            traces.append(go.Scatter3d(x=[p[-1, 0]], y=[p[-1, 1]], z=[p[-1, 2]], mode="markers", showlegend=False,
                                       marker=dict(color=AGENT_COLOURS[agent], size=5, symbol="diamond"),
                                       hovertext=f"{AGENTS[agent]} at step {k}", hoverinfo="text"))
        return traces

    fixed = [
        go.Scatter3d(x=[path[0, a, 0]], y=[path[0, a, 1]], z=[path[0, a, 2]], mode="markers", name=f"{AGENTS[a]} start",
                     marker=dict(color=AGENT_COLOURS[a], size=6, symbol="circle-open"))
        for a in agents
    ]
    fixed += [go.Scatter3d(x=[0], y=[0], z=[0], mode="markers", name="terminal", marker=dict(color="black", size=4)),
              sphere(game.terminal_sphere_radius)]
    end = path[-1]
    if episode.outcome == Outcome.CAPTURED:
        fixed.append(go.Scatter3d(x=[end[TARGETER, 0]], y=[end[TARGETER, 1]], z=[end[TARGETER, 2]], mode="markers",
                                  name="capture of T", marker=dict(color="black", size=7, symbol="x")))
    elif episode.outcome == Outcome.ATTACKER_INTERCEPTED:
        fixed.append(go.Scatter3d(x=[end[ATTACKER, 0]], y=[end[ATTACKER, 1]], z=[end[ATTACKER, 2]], mode="markers",
                                  name="capture of A", marker=dict(color="black", size=7, symbol="x")))
    fig = go.Figure(data=moving(steps) + fixed)
    moving_traces = list(range(2 * len(agents)))
    fig.frames = [go.Frame(data=moving(k), traces=moving_traces, name=str(k)) for k in range(steps + 1)]
    # Equal, fixed axes: turns keep their shape and the scene does not jump between frames.
    points = np.vstack((path.reshape(-1, 3), np.zeros((1, 3))))
    centre = (points.max(axis=0) + points.min(axis=0)) / 2
    half = max(np.max(points.max(axis=0) - points.min(axis=0)) / 2, game.terminal_sphere_radius) * 1.05
    axes = {name: dict(range=[centre[i] - half, centre[i] + half], title=name) for i, name in enumerate("xyz")}
    slider = dict(active=steps, currentvalue=dict(prefix="step "), pad=dict(t=30), steps=[
        dict(label=str(k), method="animate", args=[[str(k)], dict(mode="immediate", frame=dict(duration=0, redraw=True),
                                                                  transition=dict(duration=0))])
        for k in range(steps + 1)
    ])
    play = dict(type="buttons", showactive=False, x=0.0, y=0.0, xanchor="left", yanchor="top", direction="left", buttons=[
        dict(label="play", method="animate",
             args=[None, dict(frame=dict(duration=80, redraw=True), fromcurrent=True, transition=dict(duration=0))]),
        dict(label="pause", method="animate", args=[[None], dict(mode="immediate", frame=dict(duration=0, redraw=False))]),
    ])
    fig.update_layout(
        title=f"{episode.side} {episode.label}: {episode.outcome.label} after {steps} steps<br><sub>{episode.pairing}</sub>",
        scene=dict(xaxis=axes["x"], yaxis=axes["y"], zaxis=axes["z"], aspectmode="cube"),
        sliders=[slider], updatemenus=[play], height=620, margin=dict(l=0, r=0, t=70, b=0),
        legend=dict(x=0, y=1, font_size=10),
    )
    return fig


def curves_figure(data: ReportData) -> go.Figure:
    """The learning curves of ``curves.png``: a row per (learner, opponent), a panel per quantity,
    the scripted players and the untrained version 0 as dashed and dotted lines."""
    curves, terminal_reward = data.curves, data.run.game.terminal_reward
    # Titles on two lines, the opponent then the quantity (the learner is on the x axis), so that a
    # long name stays over its own panel.
    titles = [f"vs {c.opponent.name}<br>{q.title}" for c in curves for q in quantities(c.learner)]
    fig = make_subplots(rows=len(curves), cols=2, subplot_titles=titles, vertical_spacing=0.35 / max(1, len(curves)))
    fig.update_annotations(font_size=13)  # the subplot titles
    in_legend: set[str] = set()
    for row, curve in enumerate(curves, start=1):
        for col, quantity in enumerate(quantities(curve.learner), start=1):
            y = [quantity.value(s, curve.learner, terminal_reward) for s in curve.stats]
            fig.add_trace(go.Scatter(x=curve.env_steps, y=y, mode="lines+markers", name=curve.learner.name,
                                     line={"color": "#1f77b4"}, showlegend=False), row=row, col=col)
            # The reference lines are named in the legend (one entry each, toggling it in every panel)
            # and on hover: labels at the lines overlapped wherever two references were close.
            ends = [min(curve.env_steps), max(curve.env_steps)] if curve.env_steps else []
            for kind, name, stats in curve.references:
                label = "untrained (version 0)" if kind == "untrained" else name
                value = quantity.value(stats, curve.learner, terminal_reward)
                fig.add_trace(go.Scatter(
                    x=ends, y=[value] * len(ends), mode="lines", name=label, legendgroup=label,
                    showlegend=label not in in_legend, hovertemplate=f"{label}: %{{y:.3f}}<extra></extra>",
                    line={"color": reference_colour(kind, name), "dash": "dot" if kind == "untrained" else "dash", "width": 1},
                ), row=row, col=col)
                in_legend.add(label)
            fig.update_xaxes(title_text=f"env steps of {curve.learner.name}", row=row, col=col)
    fig.update_layout(height=340 * max(1, len(curves)), margin={"t": 70, "b": 40},
                      legend_title_text="reference lines (click to hide)")
    return fig


def generations_figure(lines: list[GenerationLine]) -> go.Figure:
    """``plots.generations_plot``, interactive."""
    fig = make_subplots(rows=1, cols=2, shared_yaxes=True, subplot_titles=[PANEL_TITLES[s] for s in SIDES])
    for column, side in enumerate(SIDES, start=1):
        for line in (line for line in lines if line.side == side):
            below, above = line.error_bars()
            fig.add_trace(go.Scatter(
                x=line.versions, y=line.rates, name=line.label, mode="lines+markers",
                line=dict(dash="solid" if line.kind == "snapshot" else "dash"),
                error_y=dict(type="data", symmetric=False, array=above, arrayminus=below),
                customdata=list(zip(line.wins, line.games)),
                hovertemplate="version %{x}: %{y:.3f} (%{customdata[0]} of %{customdata[1]} games)",
            ), row=1, col=column)
        fig.update_xaxes(title_text="snapshot version", dtick=1, row=1, col=column)
    fig.update_yaxes(title_text="win rate of the snapshot", range=[-0.03, 1.03], row=1, col=1)
    fig.update_layout(title=GENERATIONS_TITLE, height=460)
    return fig


def meta_game_html(data: ReportData) -> list[str]:
    if data.meta is None:
        return [f"<p>No meta-game: {html.escape(NO_META_GAME)}</p>"]
    return [f"<p>{html.escape(data.meta.value_line())}</p>",
            f"<p>{html.escape(GROUP_TITLE)}:</p>", html_table(GROUP_HEADER, data.meta.group_rows()),
            f"<p class='note'>{html.escape(GROUP_NOTE)}</p>",
            f"<p>{html.escape(MIXTURE_TITLE)}:</p>", html_table(MIXTURE_HEADER, data.meta.mixture_rows()),
            f"<p class='note'>{html.escape(META_GAME_NOTE)}</p>"]


def class_rates_html(data: ReportData) -> list[str]:
    table = class_rate_table(data)
    if table is None:
        return [f"<p class='note'>{html.escape(NO_CLASS_RATES)}</p>"]
    return [f"<p>{html.escape(CLASS_RATES_NOTE)}</p>", html_table(*table)]


def exploitability_figure(curves: dict[tuple[str, str, int], list[Exploitability]]) -> go.Figure:
    """``league.analysis.exploitability.exploitability_curves`` (as ``plots.exploitability_plot``)."""
    fig = go.Figure()
    for (side, games, budget), items in sorted(curves.items()):
        x = [e.exploited.iteration for e in items]
        bounds = [e.bounds() for e in items]
        colour = SIDE_COLOURS[other_side(side)]
        fig.add_trace(go.Scatter(
            x=x, y=[e.mean for e in items], mode="lines+markers", line_color=colour,
            name=f"best responses against nash-{side}@K ({budget:,} env steps, {games} games)",
            error_y={"type": "data", "symmetric": False, "array": [high - e.mean for e, (_, high) in zip(items, bounds)],
                     "arrayminus": [e.mean - low for e, (low, _) in zip(items, bounds)]},
        ))
        members = [(k, e.baseline.member_rate) for k, e in zip(x, items) if e.baseline.member is not None]
        if members:
            fig.add_trace(go.Scatter(x=[k for k, _ in members], y=[r for _, r in members], mode="lines+markers",
                                     line={"color": colour, "dash": "dash"}, name=f"best league {other_side(side)} at K"))
    fig.update_layout(title=CURVE_TITLE, xaxis_title="iteration K", yaxis_title="win rate against the mixture",
                      yaxis_range=[0, 1], height=420)
    return fig


def exploitability_html(data: ReportData) -> list[str]:
    if not data.exploitability:
        return [f"<p>{html.escape(NO_EXPLOITABILITY)}</p>"]
    curves = exploitability_curves(data.exploitability)
    return [f"<p>{html.escape(EXPLOITABILITY_NOTE)}</p>",
            html_table(EXPLOITABILITY_HEADER, [e.row() for e in data.exploitability]),
            *([f"<p>{html.escape(CURVE_NOTE)}</p>", figure_div(exploitability_figure(curves), "exploitability")] if curves else [])]


def write(data: ReportData, out: Path) -> None:
    """Write the page to ``out`` (through a temporary file: never a half-written report)."""
    parts = [
        f"<h1>Report: {html.escape(data.run.name)}</h1>", f"<p>{html.escape(data.summary)}</p>",
        "<h2>Table 1 analogue</h2>",
        "<p>The newest attacker snapshot of each reward method against the paper's training opponent (T to the "
        "terminal while avoiding A, D pursuing A). The paper's starting positions are not published, so compare the "
        "ordering, not the values.</p>",
        html_table(TABLE_ONE_HEADER, table_one_rows(data)),
        "<h2>By start class</h2>", *class_rates_html(data),
        "<h2>Payoff matrix</h2>", figure_div(payoff_figure(data), "payoff"),
        "<h2>Meta-game</h2>", *meta_game_html(data),
        "<h2>Progress over generations</h2>", f"<p>{html.escape(GENERATIONS_NOTE)}</p>",
        figure_div(generations_figure(data.generations), "generations"),
        *(f"<p class='note'>{html.escape(text)}</p>" for text in data.missing_generations),
        "<h2>Exploitability</h2>", *exploitability_html(data),
        "<h2>Ratings</h2>", figure_div(ratings_figure(data), "ratings"), f"<p>{html.escape(RATINGS_NOTE)}</p>", html_table(RATINGS_HEADER, rating_rows(data)),
        "<h2>Learner win rates in training</h2>",
        figure_div(line_figure(data.win_rates, data.phases, "win rate in training", "learner win rates (per iteration)"),
                   "win-rates"),
        "<h2>Episode returns</h2>",
        figure_div(line_figure(data.returns, data.phases, "mean episode return", "episode returns of the learners"),
                   "returns"),
        "<h2>Learning curves</h2>",
        *([f"<p>{html.escape(CURVES_NOTE)}</p>", figure_div(curves_figure(data), "learning-curves")] if data.curves else
          ["<p class='note'>No learning curves recorded (<code>evaluation.curve_every_env_steps</code> is 0, "
           "or no learner reached it).</p>"]),
        "<h2>Trajectories</h2>",
        "<p class='note'>Drag to rotate, scroll to zoom; the slider and the play button step through the game.</p>",
        "<div class='scenes'>",
    ]
    for episode in data.episodes:
        parts.append("<div>" + figure_div(trajectory_figure(episode, data.run.game),
                                          f"trajectory-{episode.side}-{episode.label}") + "</div>")
    parts.append("</div>")
    parts += [f"<p class='note'>{html.escape(text)}</p>" for text in data.missing_episodes]
    write_page(f"Report: {data.run.name}", parts, out)


def write_page(title: str, parts: list[str], out: Path) -> None:
    """One self-contained page (plotly's JavaScript inside) at ``out``, through a temporary file."""
    page = (
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
        f"<title>{html.escape(title)}</title><style>{PAGE_STYLE}</style>"
        f"<script type='text/javascript'>{get_plotlyjs()}</script></head><body>" + "\n".join(parts) + "</body></html>"
    )
    partial = out.with_name(out.name + ".partial")
    partial.write_text(page, encoding="utf-8")
    partial.replace(out)

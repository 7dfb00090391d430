"""What the report and the league's numbers show: games counted once, the HTML page in a browser, progress lines."""

import html
import re
import shutil
import sqlite3

import matplotlib.pyplot as plt
import numpy as np
import pytest
from PIL import Image

from envs.agents import ATTACKER, DEFENDER
from league.reports.page_check import check_page, find_chromium
from league.evaluate import main as evaluate_main
from league.analysis.statistics import wilson_interval
from league.core.payoff import aggregate
from league.report import build_report
from league.reports.html import AGENT_COLOURS
from league.state.store import LeagueStore



def pair_numbers(run_dir):
    """Each frozen pair's (attacker wins, games) as the report and the ratings count them, and the players' games."""
    store = LeagueStore(run_dir)
    try:
        frozen = {p.id for p in store.players() if p.kind != "learner"}
        payoff = aggregate(store.newest_evaluation_rows())
        counted = aggregate(store.counted_results())
        return {pair: n for pair, n in payoff.items() if set(pair) <= frozen}, counted, store.latest_ratings()
    finally:
        store.close()


def test_repeated_evaluation_leaves_games_and_interval_unchanged(run_copy):
    before, counted_before, _ = pair_numbers(run_copy)
    assert before, "the tiny run evaluates its frozen pairs at the end"
    # Play each pair's newest evaluation games (the same fixed games) twice more; other tests
    # may have evaluated the shared tiny run with another number of games before the copy.
    [games] = {n for _, n in before.values()}
    for _ in range(2):
        assert evaluate_main(["--run-dir", str(run_copy), "--episodes", str(games), "--workers", "0"]) == 0
    after, counted_after, ratings = pair_numbers(run_copy)
    assert after == before
    assert {pair: wilson_interval(*after[pair]) for pair in after} == {pair: wilson_interval(*before[pair]) for pair in before}
    assert counted_after == counted_before
    with sqlite3.connect(run_copy / "league.db") as db:
        players = {row[0] for row in db.execute("SELECT id FROM players")}
    assert set(ratings) == players  # every player played, so every player is rated (none left at a prior)


def test_a_newer_evaluation_with_more_games_replaces_the_old_one(run_copy):
    before, _, _ = pair_numbers(run_copy)
    assert evaluate_main(["--run-dir", str(run_copy), "--episodes", "25", "--workers", "0"]) == 0
    after, _, _ = pair_numbers(run_copy)
    assert set(after) == set(before) and {n for _, n in after.values()} == {25}


def test_progress_log_is_one_plain_line_per_iteration_under_its_own_phase(tiny_run):
    lines = (tiny_run.parent / "run.log").read_text().splitlines()
    progress = [line for line in lines if " | iter " in line]
    with sqlite3.connect(tiny_run / "league.db") as db:
        phases = dict(db.execute("SELECT iteration, phase FROM iterations"))
    assert len(progress) == len(phases)
    pattern = re.compile(
        r"^\d\d:\d\d:\d\d phase (\d)/2 (attacker|team) +\| iter +(\d+) \| +\d+ env steps in all \| +\d+ steps/s \| "
        r"sample \d+\.\d s, learn \d+\.\d s(, eval \d+\.\d s)? \| (attacker|team) win rate (\d\.\d\d) over (\d+) ep"
    )
    for line in progress:
        match = pattern.match(line)
        assert match, line
        phase, iteration, episodes = int(match[1]), int(match[3]), int(match[7])
        assert phase == phases[iteration] + 1  # the iteration that ends a phase is printed under that phase
        assert episodes > 0
    assert not any("progress.py" in line for line in lines)


@pytest.fixture(scope="module")
def report_dir(tiny_run_once, tmp_path_factory):
    """The report of a copy of the tiny run (the run is shared: a report inside it would be in every copy made after)."""
    run = tmp_path_factory.mktemp("report") / "run"
    shutil.copytree(tiny_run_once, run)
    build_report(run)
    return run / "report"


def test_report_page_is_self_contained_with_a_3d_scene_per_shown_game(report_dir):
    page = (report_dir / "index.html").read_text()
    assert "<script src" not in page and "<link" not in page  # nothing to fetch (the browser check also watches)
    assert "plotly.js v" in page  # the library itself is inside
    shown = sorted(p.name for p in report_dir.glob("trajectory_*.png"))
    scenes = re.findall(r"id=\"(trajectory-\w+-\w+)\"", page)
    assert sorted(s.replace("-", "_") + ".png" for s in scenes) == shown
    text = (report_dir / "report.md").read_text()
    for side in ("attacker", "team"):  # a missing won or lost game is said, not left out silently
        for label in ("won", "lost"):
            if f"trajectory_{side}_{label}.png" not in shown:
                assert ("never won" if label == "won" else "never lost") in text


def test_the_report_shows_each_groups_nash_range_beside_the_vertex(report_dir, tiny_run):
    from league.analysis.nash import GROUP_HEADER, MIXTURE_TITLE, league_meta_game

    store = LeagueStore(tiny_run)
    try:
        meta, _ = league_meta_game(store.players(), store.newest_evaluation_rows())
    finally:
        store.close()
    rows = meta.group_rows()
    assert {row[0] for row in rows} == {"attacker", "team"}
    text = (report_dir / "report.md").read_text()
    page = (report_dir / "index.html").read_text()
    assert "| " + " | ".join(GROUP_HEADER) + " |" in text and MIXTURE_TITLE in text
    assert "".join(f"<th>{h}</th>" for h in GROUP_HEADER) in page and MIXTURE_TITLE in page
    for row in rows:
        assert "| " + " | ".join(row) + " |" in text
        assert "<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" in page


def colour_pixels(png: bytes, hex_colour: str, tolerance: int = 40) -> int:
    """Pixels within ``tolerance`` per channel of ``hex_colour`` (antialiasing and lighting shift the shade)."""
    import io

    image = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)
    target = np.array([int(hex_colour[i : i + 2], 16) for i in (1, 3, 5)])
    return int(np.all(np.abs(image - target) <= tolerance, axis=-1).sum())


def test_report_page_opens_in_a_browser_without_errors_and_draws_the_3d_scene(report_dir, tmp_path):
    chromium = find_chromium()
    if chromium is None:
        pytest.skip("no Chromium installed (Debian: apt-get install chromium): the browser check cannot run")
    check = check_page(report_dir / "index.html", chromium)
    assert check.errors == []
    assert check.fetched == []  # opens offline: nothing but the file itself is requested
    scenes = len(list(report_dir.glob("trajectory_*.png")))
    assert check.scenes == scenes > 0
    assert check.figures == scenes + 6  # payoff, generations, ratings, win rates, returns, learning curves
    (tmp_path / "scene.png").write_bytes(check.screenshot)
    # The scene is drawn (WebGL), not only its frame: the agents' paths are in the screenshot.
    for agent in (ATTACKER, DEFENDER):
        assert colour_pixels(check.screenshot, AGENT_COLOURS[agent]) > 200, agent


def test_browser_check_reports_console_errors(tmp_path):
    chromium = find_chromium()
    if chromium is None:
        pytest.skip("no Chromium installed (Debian: apt-get install chromium): the browser check cannot run")
    page = tmp_path / "broken.html"
    page.write_text("<html><body><script>console.error('bad thing'); missingFunction();</script></body></html>")
    check = check_page(page, chromium, settle_seconds=0.5)
    assert any("bad thing" in e for e in check.errors) and any("missingFunction" in e for e in check.errors)


def test_status_of_a_finished_run_says_finished_with_its_average_speed(tiny_run):
    from league.reports.run_standing import run_line
    from league.state.run_dir import run_state

    store = LeagueStore(tiny_run)
    try:
        last, seconds = store.last_iteration(), store.training_seconds()
        line = run_line(store, run_state(tiny_run))
    finally:
        store.close()
    assert line.startswith(f"finished: iteration {last['iteration']}, {last['env_steps']} env steps")
    assert line.endswith(f"{last['env_steps'] / seconds:.0f} env steps/s on average")


def payoff_data(monkeypatch, rows: int, columns: int):
    """A league of ``rows`` attackers and ``columns`` teams, long scripted names among them."""
    from types import SimpleNamespace

    from league.reports import html as report_html, plots

    grid = np.linspace(0, 1, rows * columns).reshape(rows, columns)
    for module in (plots, report_html):
        monkeypatch.setattr(module, "payoff_grid", lambda data: grid)
    named = lambda names: [SimpleNamespace(name=name) for name in names]  # noqa: E731
    attackers = named(["scripted-proportional_navigation", *(f"attacker-m2-v{i}" for i in range(rows - 1))])
    teams = named(["scripted-avoid_oncoming_attacker+bisector_intercept", *(f"team-v{i}" for i in range(columns - 1))])
    return SimpleNamespace(attackers=attackers, teams=teams)


@pytest.mark.parametrize("rows, columns", [(3, 12), (12, 2), (6, 8), (1, 1)])
def test_the_payoff_heat_map_png_has_square_cells_and_its_title_clear(monkeypatch, rows, columns):
    # The flagship's (6 attackers, 8 teams) was a strip: cells 2.5 times wider than high.
    from league.reports.plots import heat_map_figure

    fig = heat_map_figure(payoff_data(monkeypatch, rows, columns))
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    ax, colour_bar = fig.axes
    box = ax.get_window_extent(renderer)
    cell_width, cell_height = box.width / columns, box.height / rows
    assert 0.95 <= cell_width / cell_height <= 1.05 and cell_height >= 0.5 * fig.dpi, (cell_width, cell_height)
    title = fig._suptitle.get_window_extent(renderer)
    assert not title.overlaps(colour_bar.get_window_extent(renderer)) and not title.overlaps(box)
    plt.close(fig)


def test_the_payoff_heat_map_page_has_square_cells_and_room_for_the_names(monkeypatch):
    from league.reports.html import payoff_figure

    data = payoff_data(monkeypatch, 3, 12)
    layout = payoff_figure(data).layout
    assert layout.yaxis.scaleanchor == "x"  # square cells, however wide the page
    # The teams' names, turned by the tick angle, at about 6 px a character, 40 px a row, a title.
    names = max(len(t.name) for t in data.teams) * 6 * np.sin(np.radians(abs(layout.xaxis.tickangle)))
    assert layout.height >= 80 + 40 * 3 + names, layout.height


def test_the_learning_curves_page_names_reference_lines_in_the_legend_not_over_each_other(tiny_run):
    from league.config import saved_run_config
    from league.reports.data import gather
    from league.reports.html import curves_figure

    store = LeagueStore(tiny_run)
    try:
        data = gather(store, saved_run_config(tiny_run))
    finally:
        store.close()
    fig = curves_figure(data)
    references = {(kind, name) for curve in data.curves for kind, name, _ in curve.references}
    assert references
    # Only the panels' titles are written on the figure: the reference lines are legend entries, once each.
    assert fig.layout.annotations and all(a.text.startswith("vs ") and "<br>" in a.text for a in fig.layout.annotations)
    legend = [t.name for t in fig.data if t.showlegend is not False]
    expected = {"untrained (version 0)" if kind == "untrained" else name for kind, name in references}
    assert sorted(legend) == sorted(expected)


def test_the_report_page_has_the_learning_curves_of_report_md(tiny_run, report_dir):
    from league.evaluation.learning_curves import read_curves

    store = LeagueStore(tiny_run)
    curves = read_curves(store)
    store.close()
    assert curves  # the tiny run records curves
    page = (report_dir / "index.html").read_text()
    assert 'id="learning-curves"' in page
    for curve in curves:
        assert f"vs {curve.opponent.name}\\u003cbr\\u003ewin rate" in page or f"vs {curve.opponent.name}<br>win rate" in page
        assert f"env steps of {curve.learner.name}" in page
    assert "learning curves" in (report_dir / "report.md").read_text().lower()


def test_replay_writes_a_page_and_a_png_of_one_fixed_game(tiny_run, tmp_path):
    from league.replay import main as replay_main

    out = tmp_path / "replay.html"
    args = ["--run-dir", str(tiny_run), "--attacker", "attacker-m2-v1", "--team", "scripted-avoid_attacker+pure_pursuit"]
    assert replay_main([*args, "--game", "2", "--out", str(out)]) == 0
    assert out.exists() and Image.open(out.with_suffix(".png")).size[0] > 300
    assert 'id="replay"' in out.read_text() and "(game 2)" in out.read_text()
    assert replay_main([*args[:4], "--team", "no-such-team"]) == 2
    chromium = find_chromium()
    if chromium is None:
        pytest.skip("no Chromium installed (Debian: apt-get install chromium): the browser check cannot run")
    check = check_page(out, chromium)
    assert check.errors == [] and check.fetched == [] and check.scenes == 1


def test_plots_label_what_they_draw(tiny_run):
    # curves.png: env-step ticks ran together ("1000001200001400001600001800000"); ratings.png:
    # a player rated once had a legend entry and nothing drawn, and the final refit was unexplained.
    from league.config import saved_run_config
    from league.evaluation.learning_curves import read_curves
    from league.reports.data import gather
    from league.reports.plots import curves_figure, ratings_figure

    store = LeagueStore(tiny_run)
    try:
        curves = read_curves(store)
        data = gather(store, saved_run_config(tiny_run))
    finally:
        store.close()
    fig = curves_figure([[c] for c in curves], 0.0, "curves")
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        labels = [t for t in ax.get_xticklabels() if t.get_text()]
        assert 2 <= len(labels) <= 6 and all(len(t.get_text()) <= 5 for t in labels), [t.get_text() for t in labels]
        boxes = [t.get_window_extent(renderer) for t in labels]
        assert all(a.x1 <= b.x0 for a, b in zip(boxes, boxes[1:]))  # side by side, none over the next
    fig = ratings_figure(data)
    for ax in fig.axes:
        legend = ax.get_legend()
        for handle, text in zip(legend.legend_handles, legend.get_texts()):
            if text.get_text().startswith(("snapshots", "final evaluation")):
                continue  # a key for the grey lines, and the refit's vertical line
            assert handle.get_marker() not in (None, "None", ""), text.get_text()  # one rating is one visible point
        assert any("final evaluation" in t.get_text() for t in legend.get_texts())


def test_the_report_gives_each_trained_pair_its_win_rate_by_start_class_and_free_losses(report_dir, tiny_run):
    from league.config import saved_run_config
    from league.core.payoff import attacker_won_games
    from league.evaluation.by_class import class_header, game_classes
    from league.evaluation.results import game_outcomes
    from envs.start_classes import win_rates_by_class

    store = LeagueStore(tiny_run)
    try:
        names = {p.id: p for p in store.players()}
        outcomes = game_outcomes(store, "dev")
    finally:
        store.close()
    game = saved_run_config(tiny_run).game
    classes = game_classes(game, "dev", max(len(o) for o in outcomes.values()))
    text = (report_dir / "report.md").read_text()
    page = (report_dir / "index.html").read_text()
    header = ["attacker", "team", *class_header(classes)]
    assert "| " + " | ".join(header) + " |" in text
    assert "".join(f"<th>{html.escape(h)}</th>" for h in header) in page
    shown = 0
    for (a, t), games in outcomes.items():
        if names[a].kind == "scripted" and names[t].kind == "scripted":
            continue
        rates = win_rates_by_class(attacker_won_games(games), classes[: len(games)])
        cells = ["-" if r is None else f"{r:.3f}" for r in rates.values()]
        team_free = cells[0]  # the attacker's wins on T-race starts
        attacker_free = "-" if rates["a_certain"] is None else f"{1 - rates['a_certain']:.3f}"
        row = [names[a].name, names[t].name, *cells, team_free, attacker_free]
        assert "| " + " | ".join(row) + " |" in text
        shown += 1
    assert shown > 0

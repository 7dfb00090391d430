"""Progress over generations (the report's, and several runs' in league.curves), meta-game and Nash-averaged ratings."""

import shutil
import sqlite3

import pytest
from PIL import Image

from league.config import saved_run_config
from league.analysis.generations import generation_lines
from league.reports.html import generations_figure
from league.reports.plots import generations_plot
from league.core.players import Player
from league.report import build_report
from league.reports.data import gather
from league.state.store import LeagueStore
from league.studies.seed_curves import study

A0 = Player("attacker", "snapshot", 0, 2, id=1)
A1 = Player("attacker", "snapshot", 1, 2, id=2)
A1_M3 = Player("attacker", "snapshot", 1, 3, id=3)
T0 = Player("team", "snapshot", 0, id=4)
PURSUIT = Player("attacker", "scripted", 0, scripted_attacker="pure_pursuit", id=5)
AVOID = Player("team", "scripted", 0, scripted_targeter="avoid_attacker", scripted_defender="pure_pursuit", id=6)
STRAIGHT = Player("team", "scripted", 0, scripted_targeter="straight", scripted_defender="pure_pursuit", id=7)
TX1 = Player("team", "exploiter_snapshot", 1, id=8)
AX1 = Player("attacker", "exploiter_snapshot", 1, 2, id=9)


def test_each_lineage_against_each_scripted_opponent_by_version():
    payoff = {(A1.id, AVOID.id): (7, 10), (A0.id, AVOID.id): (2, 10), (A0.id, STRAIGHT.id): (9, 10),
              (A1.id, STRAIGHT.id): (8, 10), (A1_M3.id, AVOID.id): (5, 10), (PURSUIT.id, T0.id): (3, 10)}
    lines, missing = generation_lines([A1, A0, A1_M3, T0, PURSUIT, AVOID, STRAIGHT], payoff)
    by_label = {line.label: line for line in lines}
    assert set(by_label) == {
        "attacker-m2 vs scripted-avoid_attacker+pure_pursuit", "attacker-m2 vs scripted-straight+pure_pursuit",
        "attacker-m3 vs scripted-avoid_attacker+pure_pursuit", "attacker-m3 vs scripted-straight+pure_pursuit",
        "team vs scripted-pure_pursuit",
    }
    line = by_label["attacker-m2 vs scripted-avoid_attacker+pure_pursuit"]
    assert (line.versions, line.rates) == ([0, 1], [0.2, 0.7])  # by version, whatever the players' order
    team = by_label["team vs scripted-pure_pursuit"]
    assert (team.side, team.versions, team.rates) == ("team", [0], [0.7])  # the team's own win rate
    assert by_label["attacker-m3 vs scripted-straight+pure_pursuit"].versions == []
    assert missing == ["attacker-m3-v1 vs scripted-straight+pure_pursuit not evaluated"]


def test_an_exploiters_snapshots_are_a_lineage_of_their_own():
    payoff = {(PURSUIT.id, T0.id): (3, 10), (PURSUIT.id, TX1.id): (1, 10), (AX1.id, AVOID.id): (6, 10)}
    lines, missing = generation_lines([TX1, T0, AX1, A0, PURSUIT, AVOID, STRAIGHT], payoff)
    by_label = {line.label: line for line in lines}
    assert [line.label for line in lines if line.side == "team"] == [
        "team vs scripted-pure_pursuit", "team-exploiter vs scripted-pure_pursuit"  # the learner's lineage first
    ]
    exploiter = by_label["team-exploiter vs scripted-pure_pursuit"]
    assert (exploiter.kind, exploiter.versions, exploiter.rates) == ("exploiter_snapshot", [1], [0.9])
    assert by_label["team vs scripted-pure_pursuit"].versions == [0]  # the exploiter's points are not the learner's
    assert by_label["attacker-m2-exploiter vs scripted-avoid_attacker+pure_pursuit"].rates == [0.6]
    assert by_label["attacker-m2 vs scripted-avoid_attacker+pure_pursuit"].kind == "snapshot"
    assert "attacker-m2-exploiter-v1 vs scripted-straight+pure_pursuit not evaluated" in missing
    dashes = {trace.name: trace.line.dash for trace in generations_figure(lines).data}
    assert dashes["team-exploiter vs scripted-pure_pursuit"] == "dash" and dashes["team vs scripted-pure_pursuit"] == "solid"


def test_plots_draw_rates_of_0_and_1(tmp_path):
    # A Wilson interval's end at 10 of 10 wins is 1 - 1e-16, just below the rate.
    lines, _ = generation_lines([A0, A1, AVOID], {(A0.id, AVOID.id): (0, 10), (A1.id, AVOID.id): (10, 10)})
    below, above = lines[0].error_bars()
    assert min(below + above) >= 0 and above[0] > 0.2 and below[1] > 0.2
    generations_plot(lines, tmp_path / "generations.png")
    assert Image.open(tmp_path / "generations.png").size[0] > 1000
    assert generations_figure(lines).data[0].error_y.array == tuple(above)



def test_report_plays_a_missing_pair_and_draws_the_generations(run_copy):
    store = LeagueStore(run_copy)
    names = {p.name: p for p in store.players()}
    store.close()
    snapshot, scripted = names["attacker-m2-v1"], names["scripted-avoid_attacker+pure_pursuit"]
    with sqlite3.connect(run_copy / "league.db") as db:  # as if the run had not evaluated this pair
        db.execute("DELETE FROM matches WHERE source = 'evaluation' AND attacker = ? AND team = ?", (snapshot.id, scripted.id))
    store = LeagueStore(run_copy)
    try:
        data = gather(store, saved_run_config(run_copy))  # reads only: the pair is missing
        assert "attacker-m2-v1 vs scripted-avoid_attacker+pure_pursuit not evaluated" in data.missing_generations
    finally:
        store.close()

    report = build_report(run_copy).read_text()  # plays the missing pair and records it first
    store = LeagueStore(run_copy)
    try:
        data = gather(store, saved_run_config(run_copy))
    finally:
        store.close()
    [line] = [line for line in data.generations if line.label == "attacker-m2 vs scripted-avoid_attacker+pure_pursuit"]
    assert line.versions == [0, 1] and not data.missing_generations
    assert data.payoff[(snapshot.id, scripted.id)][1] == line.games[1]  # played on the run's evaluation games
    width, height = Image.open(run_copy / "report" / "generations.png").size
    assert width > 1000 and height > 400
    assert "## Progress over generations" in report and "![generations](generations.png)" in report
    assert "## Meta-game" in report and "value" in report
    assert "## Exploitability" in report and "No best responses yet" in report
    # Every frozen player has a Nash-averaged rating in [0, 1] beside its Elo rating; learners have none.
    rows = [row.split(" | ") for row in report.splitlines() if row.startswith("| ") and row.count(" | ") == 5]
    nash = {cells[0].lstrip("| "): cells[4] for cells in rows[2:] if cells[2] in ("snapshot", "scripted", "learner")}
    assert nash["attacker-m2"] == "" and nash["team"] == ""
    assert all(0 <= float(nash[name]) <= 1 for name in nash if name not in ("attacker-m2", "team"))
    page = (run_copy / "report" / "index.html").read_text()
    assert "id='generations'" in page or 'id="generations"' in page
    assert "Nash-averaged rating" in page


def test_a_study_of_several_runs_draws_each_runs_generations(tiny_run, tmp_path):
    seeds = [tmp_path / "seed0", tmp_path / "seed1"]  # the same run twice stands for two seeds of one config
    for seed in seeds:
        shutil.copytree(tiny_run, seed)
    store = LeagueStore(seeds[1])
    names = {p.name: p for p in store.players()}
    store.close()
    snapshot, scripted = names["attacker-m2-v1"], names["scripted-avoid_attacker+pure_pursuit"]
    with sqlite3.connect(seeds[1] / "league.db") as db:  # seed1 misses one point
        db.execute("DELETE FROM matches WHERE source = 'evaluation' AND attacker = ? AND team = ?", (snapshot.id, scripted.id))

    study(seeds, tmp_path / "study")
    one_run = tmp_path / "one.png"
    store = LeagueStore(seeds[0])
    try:
        generations_plot(gather(store, saved_run_config(seeds[0])).generations, one_run)
    finally:
        store.close()
    width, height = Image.open(tmp_path / "study" / "generations.png").size
    assert (width, height) == (Image.open(one_run).size[0], 2 * Image.open(one_run).size[1])  # a row per run
    text = (tmp_path / "study" / "curves.md").read_text()
    progress = text[text.index("## Progress over generations"):]
    seed0, seed1 = progress.split("### seed1")
    assert "### seed0" in seed0
    first_and_last = "| attacker-m2 | scripted-avoid_attacker+pure_pursuit | v0 | "
    row = next(line for line in seed0.splitlines() if line.startswith(first_and_last))
    assert "| v1 | " in row and row.count("[") == 2  # the first and the last snapshot, each with its interval
    assert "| team | scripted-lead_intercept | v0 | " in seed0
    assert "attacker-m2-v1 vs scripted-avoid_attacker+pure_pursuit not evaluated" in seed1
    assert "not evaluated" not in seed0
    row = next(line for line in seed1.splitlines() if line.startswith(first_and_last))
    assert "| v1 | " not in row  # its last evaluated snapshot is v0

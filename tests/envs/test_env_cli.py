"""The envs command lines: the scripted table and the episode plot."""

import itertools
import subprocess
import sys

import pytest

from envs import match, render
from envs.config import GameConfig
from envs.scenarios import evaluation_scenarios
from envs.scripted import PLAYERS


def test_match_prints_a_row_per_scripted_matchup(capsys):
    assert match.main(["--episodes", "20"]) == 0
    rows = {}
    for line in capsys.readouterr().out.splitlines()[3:]:  # past the scenario line, the header and its rule
        attacker, targeter, defender, rate, *counts = (cell.strip() for cell in line.strip("|").split("|"))
        assert (attacker, targeter, defender) not in rows
        rows[attacker, targeter, defender] = rate, [int(n) for n in counts]
    assert set(rows) == set(itertools.product(PLAYERS["attacker"], PLAYERS["targeter"], PLAYERS["defender"]))
    # Two matchups played here on the same 20 fixed games: the printed win rate and outcome counts
    # (captured, timeout, terminal_reached, attacker_intercepted) are theirs.
    positions = evaluation_scenarios("default", 20)
    labels = ("captured", "timeout", "terminal_reached", "attacker_intercepted")
    matchups = [
        ("pure_pursuit", "avoid_attacker", "pure_pursuit"),
        ("proportional_navigation", "avoid_attacker", "bisector_intercept"),
    ]
    for matchup in matchups:
        result = match.play(GameConfig(), match.scripted_players(*matchup), positions)
        counts = result.outcome_counts()
        assert rows[matchup] == (f"{result.attacker_wins.mean():.3f}", [counts[label] for label in labels]), matchup
    assert len({rate for rate, _ in rows.values()}) > 2  # the rows' rates differ


def test_render_writes_a_png(tmp_path, capsys):
    out = tmp_path / "episode.png"
    assert render.main(["--attacker", "lead_intercept", "--team", "scripted", "--seed", "3", "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "after" in capsys.readouterr().out


@pytest.mark.parametrize("module", ["envs.render", "envs.match"])
def test_unknown_scenario_exits_2_naming_it(module, tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", module, "--scenario", "nowhere"], capture_output=True, text=True, cwd=tmp_path
    )
    assert proc.returncode == 2
    assert "--scenario" in proc.stderr and "nowhere" in proc.stderr
    assert not any(tmp_path.iterdir())

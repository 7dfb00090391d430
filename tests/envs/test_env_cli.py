"""The envs command lines: the scripted table and the episode plot."""

import subprocess
import sys

import pytest

from envs import match, render


def test_match_prints_a_row_per_scripted_matchup(capsys):
    assert match.main(["--episodes", "20"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| lead_intercept")]
    assert len(rows) == 6  # three targeters x two defenders


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

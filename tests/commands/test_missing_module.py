"""A snapshot whose saved module was deleted: every command that plays or exports it says so in one line."""

import shutil

import pytest

from league.evaluate import main as evaluate_main
from league.export import main as export_main
from league.replay import main as replay_main
from league.report import main as report_main

COMMANDS = {
    "evaluate": lambda run, tmp: evaluate_main(["--run-dir", str(run), "--workers", "0", "--episodes", "2"]),
    "replay": lambda run, tmp: replay_main(["--run-dir", str(run), "--attacker", "attacker-m2-v1", "--team", "team-v1"]),
    "report": lambda run, tmp: report_main(["--run-dir", str(run)]),
    "export": lambda run, tmp: export_main(["--run-dir", str(run), "--player", "team-v1", "--out", str(tmp / "x.pt")]),
}


@pytest.mark.parametrize("deleted", ["players/team-v1", "players/team-v1/module_state.pkl"])
@pytest.mark.parametrize("command", COMMANDS)
def test_a_missing_saved_module_is_one_line_naming_the_player_and_the_path(run_copy, tmp_path, capsys, command, deleted):
    gone = run_copy / deleted
    shutil.rmtree(gone) if gone.is_dir() else gone.unlink()
    assert COMMANDS[command](run_copy, tmp_path) == 2
    # evaluate may report its progress over the pairs it played before it reached team-v1
    lines = [line for line in capsys.readouterr().err.strip().splitlines() if not line.startswith("evaluating on ")]
    assert len(lines) == 1
    [err] = lines
    assert err.startswith("error: the saved module of player team-v1 is missing: ")
    assert err.endswith(f"/{run_copy.name}/{deleted} not found (deleted or moved?)")  # the path, absolute or as given
    assert not (run_copy / "report").exists()  # report: no empty folder left behind
    assert not (tmp_path / "x.pt").exists()

"""``league.status``: training, stopped or finished; what it says a stopped run needs; its JSON.

Each test reads a copy of the session's finished ``tiny_run``. A run that trains is stood for by
a process that holds the run directory's lock (what ``league.run`` holds while it trains), and a
SIGKILLed run by that process killed.
"""

import json
import os
import signal
import sqlite3
import subprocess
import sys
from pathlib import Path

from league import status
from league.state.store import LeagueStore

EVALUATION_FILE = "evaluation.md"  # the last file a run writes

ROOT = Path(__file__).resolve().parents[2]
HOLD_THE_LOCK = (
    "import sys, time; from pathlib import Path; from league.state.run_dir import lock_run\n"
    "lock = lock_run(Path(sys.argv[1])); print('held', flush=True); time.sleep(600)\n"
)


def status_of(run_dir: Path, capsys) -> tuple[dict, list[str]]:
    """``status --json`` and the first lines of the text."""
    assert status.main(["--run-dir", str(run_dir), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert status.main(["--run-dir", str(run_dir)]) == 0
    return data, capsys.readouterr().out.splitlines()[:3]


def test_a_finished_run_is_finished(run_copy, capsys):
    data, lines = status_of(run_copy, capsys)
    assert (data["state"], data["finished"], data["training_done"], data["next"]) == ("finished", True, True, None)
    assert lines[0].startswith("finished: iteration ")
    assert not any("--resume" in line for line in lines)


def test_a_run_whose_final_evaluation_was_interrupted_is_stopped_and_points_to_resume(run_copy, capsys):
    (run_copy / EVALUATION_FILE).unlink()  # the last thing a run writes
    data, lines = status_of(run_copy, capsys)
    resume = f"`python -m league.run --resume {run_copy}`"
    assert (data["state"], data["finished"], data["training_done"]) == ("stopped", False, True)
    assert data["next"] == f"resume with {resume}"
    assert lines[0].startswith("stopped in its final evaluation (training done): iteration ")
    assert lines[1] == f"resume with {resume}"


def test_a_sigkilled_run_is_told_from_a_training_one(run_copy, capsys):
    (run_copy / EVALUATION_FILE).unlink()
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD_THE_LOCK, str(run_copy)], stdout=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    try:
        assert holder.stdout.readline().strip() == "held"
        data, lines = status_of(run_copy, capsys)
        assert (data["state"], data["finished"], data["next"]) == ("training", False, None)
        assert lines[0].startswith("training in its final evaluation") and "--resume" not in lines[1]
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait(timeout=30)
    data, lines = status_of(run_copy, capsys)  # the kernel dropped the lock with the process
    assert (data["state"], data["finished"]) == ("stopped", False)
    assert lines[1] == f"resume with `python -m league.run --resume {run_copy}`"


def test_a_stopped_run_without_a_checkpoint_is_not_sent_to_resume(run_copy, capsys):
    import shutil

    (run_copy / EVALUATION_FILE).unlink()
    shutil.rmtree(run_copy / "checkpoints")
    data, lines = status_of(run_copy, capsys)
    assert data["state"] == "stopped" and "--resume" not in data["next"] and "start the run again" in data["next"]


def drop_evaluations_of(run_dir: Path, player: str) -> None:
    """Forget every evaluation game of ``player`` (its pairs then lack an evaluation)."""
    store = LeagueStore(run_dir)
    player_id = next(p.id for p in store.players() if p.name == player)
    store.close()
    with sqlite3.connect(run_dir / "league.db") as db:
        db.execute("DELETE FROM matches WHERE source = 'evaluation' AND (attacker = ?1 OR team = ?1)", (player_id,))


def test_no_meta_game_is_null_with_the_reason_beside_it(run_copy, capsys):
    data, _ = status_of(run_copy, capsys)
    assert data["meta_game"]["players"] and data["no_meta_game"] is None
    drop_evaluations_of(run_copy, "team-v1")
    data, _ = status_of(run_copy, capsys)
    assert data["meta_game"] is None
    assert data["no_meta_game"] == "3 of 9 pairs of frozen players not evaluated yet (python -m league.evaluate plays them)"


def test_no_rating_beside_no_games_of_the_source(run_copy, capsys):
    drop_evaluations_of(run_copy, "team")  # the learner, which also trained
    assert status.main(["--run-dir", str(run_copy), "--source", "evaluation", "--json"]) == 0
    rows = {row["player"]: row for row in json.loads(capsys.readouterr().out)["players"]}
    assert (rows["team"]["games"], rows["team"]["rating"]) == (0, None)
    assert all(row["rating"] is not None for name, row in rows.items() if row["games"])
    assert status.main(["--run-dir", str(run_copy), "--source", "evaluation"]) == 0
    table = [[cell.strip() for cell in line.split("│")[1:-1]] for line in capsys.readouterr().out.splitlines()]
    assert next(cells for cells in table if cells[:1] == ["team"])[-3:] == ["", "0", ""]  # rating, games, win rate
    assert status.main(["--run-dir", str(run_copy), "--json"]) == 0  # its training games carry its rating
    rows = {row["player"]: row for row in json.loads(capsys.readouterr().out)["players"]}
    assert rows["team"]["games"] > 0 and rows["team"]["rating"] is not None

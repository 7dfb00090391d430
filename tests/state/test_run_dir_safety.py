"""A run directory nothing can corrupt: validation before writing, clear errors for damaged
state, the run lock, a graceful stop, a full disk, a private Ray instance.

The cheap checks call the CLIs' ``main`` in this process on copies of the session's
finished ``tiny_run``; the lock, the signals and the full disk are real processes.
"""

import math
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from pydantic import ValidationError

from envs.config import GameConfig
from league import evaluate, export, report, run, status
from league.state.run_dir import LOCK_FILE, usable_checkpoints
from league.state.store import DB_NAME, TABLES, LeagueStore

TINY = """
name: tiny
seed: 1
game: {{terminal_reward: 1.0}}
ppo: {{train_batch_size: 200, minibatch_size: 100, num_epochs: 1, hidden: [16]}}
resources: {{num_cpus: 2, num_env_runners: 0, num_envs_per_env_runner: 4}}
league: {{mode: selfplay, selfplay_phases: {phases}, min_phase_episodes: 100000, phase_env_steps: {phase_steps}}}
evaluation: {{episodes: 4, workers: 0}}
checkpoint_every: 1
"""
RUN_TIMEOUT = 600
PYTHON_PATH = str(Path(__file__).resolve().parents[2])


@pytest.fixture
def tiny_config(tmp_path):
    def make(phases=1, phase_steps=200):
        path = tmp_path / f"tiny_{phases}_{phase_steps}.yaml"
        path.write_text(TINY.format(phases=phases, phase_steps=phase_steps))
        return str(path)

    return make


@pytest.fixture
def run_copy(tiny_run, tmp_path):
    """A private copy of the session's finished run, free to damage."""
    copy = tmp_path / "run"
    shutil.copytree(tiny_run, copy)
    return copy


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error: "), err
    return err


def query(run_dir: Path, sql: str):
    with sqlite3.connect(run_dir / "league.db", timeout=30) as db:
        return db.execute(sql).fetchall()


def child_env(**extra):
    return {**os.environ, "PYTHONPATH": PYTHON_PATH, **extra}


# ------------------------------------------------------------------ validation before writing
@pytest.mark.parametrize(
    "override, key",
    [
        ("seed=-1", "seed"),
        ("ppo.hidden=[-5]", "ppo.hidden.0"),
        ("ppo.hidden=[16, 0]", "ppo.hidden.1"),
        ("game.v_attacker=.inf", "game.v_attacker"),
        ("game.terminal_reward=.inf", "game.terminal_reward"),
        ("game.time_limit_factor=.inf", "game.time_limit_factor"),
        ("ppo.lr=.nan", "ppo.lr"),
        ("evaluation.custom_resources_per_worker={evaluator: -1}", "evaluation.custom_resources_per_worker.evaluator"),
    ],
)
def test_invalid_values_exit_2_naming_the_key_before_anything_is_written(tiny_config, tmp_path, capsys, override, key):
    run_dir = tmp_path / "new"
    assert run.main(["--config", tiny_config(), "--run-dir", str(run_dir), "--set", override]) == 2
    assert f"{key}:" in one_error_line(capsys)
    assert not run_dir.exists()


@pytest.mark.parametrize("field", ["terminal_reward", "time_limit_factor", "v_attacker", "sigma_a"])
def test_game_config_rejects_infinite_and_nan_values(field):
    for value in (math.inf, math.nan):
        with pytest.raises(ValidationError, match=field):
            GameConfig(**{field: value})


def test_bad_arguments_are_one_line_errors(tiny_config, tmp_path, capsys):
    a_file = tmp_path / "a_file"
    a_file.write_text("")
    assert run.main(["--config", str(tmp_path), "--run-dir", str(tmp_path / "x")]) == 2
    assert "is a directory" in one_error_line(capsys)
    assert run.main(["--config", tiny_config(), "--run-dir", str(a_file)]) == 2
    assert f"--run-dir {a_file} is a file" in one_error_line(capsys)
    assert run.main(["--config", tiny_config(), "--run-dir", str(tmp_path / "x"), "--set", "ppo.hidden=[1,"]) == 2
    assert "--set 'ppo.hidden=[1,': the value is not valid YAML" in one_error_line(capsys)
    assert run.main(["--resume", str(a_file)]) == 2
    assert "is a file, not a run directory" in one_error_line(capsys)
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("flag, value", [("--episodes", "-5"), ("--episodes", "0"), ("--workers", "-1")])
def test_evaluate_refuses_counts_out_of_range(run_copy, capsys, flag, value):
    with pytest.raises(SystemExit) as exit_:
        evaluate.main(["--run-dir", str(run_copy), flag, value])
    assert exit_.value.code == 2
    assert f"argument {flag}: must be at least" in capsys.readouterr().err


def test_export_to_an_existing_directory_is_refused_and_leaves_nothing(run_copy, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    assert export.main(["--run-dir", str(run_copy), "--player", "latest-attacker", "--out", str(out)]) == 2
    assert "is a directory" in one_error_line(capsys)
    assert list(tmp_path.glob("*.partial")) == [] and list(out.iterdir()) == []


def test_a_new_run_that_fails_while_building_removes_its_directory(tiny_config, tmp_path, monkeypatch):
    from league.rllib import bridge as rllib_bridge

    def broken_build(*args, **kwargs):
        assert (run_dir / "league.db").exists()  # the failure comes after the first writes
        raise RuntimeError("the algorithm cannot be built")

    run_dir = tmp_path / "new"
    monkeypatch.setattr(run, "start_ray", lambda *args: None)
    monkeypatch.setattr(rllib_bridge, "build_config", broken_build)
    with pytest.raises(RuntimeError, match="cannot be built"):
        run.main(["--config", tiny_config(), "--run-dir", str(run_dir)])
    assert not run_dir.exists()


# ------------------------------------------------------------------ the store
def test_league_db_appears_only_with_its_schema(tmp_path, monkeypatch):
    seen = []

    def replace(source, target):
        assert not Path(target).exists()  # nothing named league.db before this rename
        db = sqlite3.connect(source)
        seen.extend(name for (name,) in db.execute("SELECT name FROM sqlite_master WHERE type = 'table'"))
        db.close()
        return os_replace(source, target)

    os_replace = os.replace
    monkeypatch.setattr(os, "replace", replace)
    LeagueStore(tmp_path, create=True).close()
    assert set(TABLES) <= set(seen)
    assert sorted(p.name for p in tmp_path.iterdir()) == [DB_NAME]  # no partial or WAL file left


def test_rollback_forgets_an_evaluation_of_a_later_iteration(tmp_path):
    store = LeagueStore(tmp_path, create=True)
    store.set_meta("evaluated_iteration", 4)
    store.rollback_after(4)
    assert store.get_meta("evaluated_iteration") == 4
    store.rollback_after(3)  # iteration 4 and its evaluation rows will be redone
    assert store.get_meta("evaluated_iteration") is None


# ------------------------------------------------------------------ damaged state
def truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def garble(path: Path, offset: int = 0) -> None:
    data = bytearray(path.read_bytes())
    data[offset : offset + 2048] = bytes(range(256)) * 8
    path.write_bytes(data)


DAMAGES = {
    "league.db truncated": ("league.db", truncate, "league.db is damaged"),
    "league.db garbled header": ("league.db", garble, "league.db is damaged (file is not a database)"),
    "league.db garbled page": ("league.db", lambda p: garble(p, 3 * 4096), "league.db is damaged"),
    "league.db empty": ("league.db", lambda p: p.write_bytes(b""), "league.db is empty"),
    "config.yaml missing": ("config.yaml", Path.unlink, "config.yaml is missing"),
    "config.yaml unparsable": ("config.yaml", lambda p: p.write_text("name: [tiny\n"), "config.yaml: not valid YAML"),
    "config.yaml binary": ("config.yaml", lambda p: p.write_bytes(b"\xff\xfe\x00"), "config.yaml: not valid YAML"),
    "config.yaml invalid": (
        "config.yaml", lambda p: p.write_text(p.read_text().replace("seed: 3", "seed: -3")), "config.yaml: seed:"
    ),
}
CLIS = {
    "resume": lambda d: run.main(["--resume", str(d)]),
    "status": lambda d: status.main(["--run-dir", str(d)]),
    "evaluate": lambda d: evaluate.main(["--run-dir", str(d), "--workers", "0", "--episodes", "2"]),
    "report": lambda d: report.main(["--run-dir", str(d)]),
    "export": lambda d: export.main(["--run-dir", str(d), "--player", "latest-team", "--out", str(d / "team.pt")]),
}


@pytest.mark.parametrize("damage", DAMAGES)
def test_damaged_run_directories_are_one_line_errors_for_every_cli(run_copy, capsys, damage):
    name, damage_file, message = DAMAGES[damage]
    damage_file(run_copy / name)
    # (`--resume` restores a damaged league.db from its newest checkpoint's copy: see below.)
    for cli, main in CLIS.items() if name != "league.db" else [(k, v) for k, v in CLIS.items() if k != "resume"]:
        assert main(run_copy) == 2, cli
        err = one_error_line(capsys)
        assert str(run_copy / name) in err and message in err, (cli, err)
        assert "restore" in err, (cli, err)  # and what the user can do
    assert not (run_copy / "team.pt").exists()


def test_a_config_edited_after_the_start_is_refused_on_resume_naming_the_keys(run_copy, capsys):
    config = run_copy / "config.yaml"
    config.write_text(config.read_text().replace("v_attacker: 0.18", "v_attacker: 0.2").replace("lr: 0.0003", "lr: 0.001"))
    assert run.main(["--resume", str(run_copy)]) == 2
    err = one_error_line(capsys)
    assert "was changed after the run started (game.v_attacker, ppo.lr)" in err


def test_status_names_the_newest_intact_checkpoint_when_the_latest_is_deleted(run_copy, capsys):
    store = LeagueStore(run_copy)
    (newest, newest_path), (previous, previous_path) = store.checkpoints()[-1:-3:-1]
    shutil.rmtree(run_copy / newest_path)
    assert usable_checkpoints(run_copy, store) == (
        [(previous, previous_path)], [f"the checkpoint of iteration {newest} ({newest_path}) is missing"]
    )
    assert status.main(["--run-dir", str(run_copy)]) == 0
    out = capsys.readouterr().out
    assert f"last checkpoint: iteration {previous} at {previous_path}" in out
    assert f"checkpoint of iteration {newest} ({newest_path}) is missing" in out


def test_resume_falls_back_from_a_garbled_checkpoint_and_rolls_the_database_back(run_copy):
    store = LeagueStore(run_copy)
    (newest, newest_path), (previous, _) = store.checkpoints()[-1:-3:-1]
    iterations_before = query(run_copy, "SELECT * FROM iterations ORDER BY iteration")
    store.close()
    garble(run_copy / newest_path / "algorithm_state.pkl", 64)
    proc = subprocess.run(
        [sys.executable, "-m", "league.run", "--resume", str(run_copy)],
        capture_output=True, text=True, timeout=RUN_TIMEOUT, env=child_env(),
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    said = " ".join(proc.stderr.split())  # the progress console wraps lines
    assert f"resuming from the checkpoint of iteration {previous}" in said
    assert "algorithm_state.pkl differs from what was written" in said
    assert f"rolled back from iteration {newest} to {previous}" in said
    after = query(run_copy, "SELECT * FROM iterations ORDER BY iteration")
    assert after[:previous] == iterations_before[:previous]
    assert [row[0] for row in after] == list(range(1, len(after) + 1))
    assert after[-1][4] == query(run_copy, "SELECT SUM(count) FROM matches WHERE source = 'training'")[0][0]


# ------------------------------------------------------------------ real processes: lock, signals
def start(*args, **env):
    return subprocess.Popen(
        [sys.executable, "-m", "league.run", *args],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True,  # its own process group: a Ctrl-C below reaches only this run
        env=child_env(**env),
    )


def committed(run_dir: Path) -> int:
    try:
        return query(run_dir, "SELECT COUNT(*) FROM iterations")[0][0]
    except sqlite3.Error:  # not created yet
        return 0


def wait_for_iterations(proc, run_dir: Path, count: int) -> None:
    deadline = time.monotonic() + RUN_TIMEOUT
    while committed(run_dir) < count:
        assert proc.poll() is None, "the run ended before the test could signal it: " + proc.stdout.read()[-3000:]
        assert time.monotonic() < deadline, f"the run did not reach iteration {count} in time"
        time.sleep(0.3)


def stop_and_check(proc, run_dir: Path, signum: int, exit_code: int) -> int:
    """Send the signal, check the one-line report against the database; returns the iteration."""
    if signum == signal.SIGINT:
        os.killpg(proc.pid, signum)  # Ctrl-C in a terminal reaches the whole foreground group
    else:
        os.kill(proc.pid, signum)  # a scheduler's SIGTERM to the run's process
    out, _ = proc.communicate(timeout=RUN_TIMEOUT)
    assert proc.returncode == exit_code, out[-3000:]
    last_line = out.strip().splitlines()[-1]
    iteration = query(run_dir, "SELECT MAX(iteration) FROM iterations")[0][0]
    checkpoint = query(run_dir, "SELECT MAX(iteration) FROM checkpoints")[0][0]
    assert last_line == (
        f"stopped at iteration {iteration}, last checkpoint {checkpoint}, "
        f"resume with `python -m league.run --resume {run_dir}`"
    ), out[-3000:]
    assert "Traceback" not in out, out[-3000:]
    assert not list((run_dir / "checkpoints").glob("*.partial"))
    return iteration


def test_lock_readers_and_stops_by_signal_keep_the_run_continuous(tmp_path, tiny_config):
    run_dir = (tmp_path / "run").resolve()
    # Long enough (60 iterations) to be still running while the readers and signals below arrive.
    first = start("--config", tiny_config(4, 3000), "--run-dir", str(run_dir))
    deadline = time.monotonic() + RUN_TIMEOUT
    while not (run_dir / "league.db").exists():  # the lock is taken before the database is made
        assert first.poll() is None and time.monotonic() < deadline, first.stdout.read()[-3000:]
        time.sleep(0.2)

    # While it runs: a second training process is refused at once, naming the holder;
    # a reader needs no lock.
    child = {"stdout": subprocess.PIPE, "stderr": subprocess.PIPE, "text": True, "env": child_env()}
    second = subprocess.Popen([sys.executable, "-m", "league.run", "--resume", str(run_dir)], **child)
    reader = subprocess.Popen([sys.executable, "-m", "league.status", "--run-dir", str(run_dir)], **child)
    _, err = second.communicate(timeout=120)
    assert second.returncode == 2 and f"is in use by process {first.pid}" in err, err
    assert len(err.strip().splitlines()) == 1
    out, err = reader.communicate(timeout=120)
    assert reader.returncode == 0 and "scripted-lead_intercept" in out, err
    assert first.poll() is None  # all of this happened while the run was running

    wait_for_iterations(first, run_dir, 2)
    stopped_at = stop_and_check(first, run_dir, signal.SIGINT, 130)

    before = query(run_dir, "SELECT * FROM iterations ORDER BY iteration")

    resumed = start("--resume", str(run_dir))
    wait_for_iterations(resumed, run_dir, stopped_at + 1)
    stop_and_check(resumed, run_dir, signal.SIGTERM, 143)

    # The lock file stays, with the last holder's pid; the lock itself went with the process.
    assert (run_dir / LOCK_FILE).read_text().strip() == str(resumed.pid)
    last = start("--resume", str(run_dir))
    out, _ = last.communicate(timeout=RUN_TIMEOUT)
    assert last.returncode == 0, out[-3000:]

    after = query(run_dir, "SELECT * FROM iterations ORDER BY iteration")
    assert after[: len(before)] == before  # a graceful stop keeps every committed iteration
    assert [row[0] for row in after] == list(range(1, len(after) + 1))  # no gap, no repeat
    assert after[-1][4] == query(run_dir, "SELECT SUM(count) FROM matches WHERE source = 'training'")[0][0]
    versions = query(run_dir, "SELECT side, version FROM players WHERE kind = 'snapshot' ORDER BY side, version")
    assert versions == [("attacker", 0), ("attacker", 1), ("attacker", 2), ("team", 0), ("team", 1), ("team", 2)]
    assert query(run_dir, "PRAGMA integrity_check") == [("ok",)]


# ------------------------------------------------------------------ full disk, private Ray
FULL_DISK_AT_THIRD_CHECKPOINT = textwrap.dedent(
    """
    import errno, sys
    from ray.rllib.algorithms.algorithm import Algorithm

    save, calls = Algorithm.save_to_path, []

    def save_on_a_full_disk(self, path, *args, **kwargs):
        calls.append(path)
        result = save(self, path, *args, **kwargs)
        if len(calls) == 3:  # the files are written, then the last write finds the disk full
            raise OSError(errno.ENOSPC, "No space left on device", path)
        return result

    Algorithm.save_to_path = save_on_a_full_disk
    from league.run import main
    sys.exit(main(sys.argv[1:]))
    """
)


def test_a_full_disk_is_one_line_and_keeps_the_previous_checkpoint(tmp_path, tiny_config):
    run_dir = (tmp_path / "run").resolve()
    # RAY_ADDRESS names a cluster that does not exist: without --address the run must
    # start its own Ray instance and never look for another one.
    proc = subprocess.run(
        [sys.executable, "-c", FULL_DISK_AT_THIRD_CHECKPOINT, "--config", tiny_config(1, 600), "--run-dir", str(run_dir)],
        capture_output=True, text=True, timeout=RUN_TIMEOUT, env=child_env(RAY_ADDRESS="127.0.0.1:9"),
    )
    assert proc.returncode == 2, proc.stdout[-3000:] + proc.stderr[-3000:]
    last_line = proc.stderr.strip().splitlines()[-1]
    assert last_line.startswith(f"error: disk full while writing into {run_dir}: ") and "MiB free" in last_line
    assert "the last checkpoint (iteration 1) is intact" in last_line
    assert "Traceback" not in proc.stderr
    assert not list((run_dir / "checkpoints").glob("*.partial"))
    store = LeagueStore(run_dir)
    assert store.last_iteration()["iteration"] == 1  # iteration 2's transaction never committed
    assert usable_checkpoints(run_dir, store)[0][0] == (1, "checkpoints/iter_000001")


# ------------------------------------------------------------------ PettingZoo input errors
def test_pettingzoo_env_refuses_step_before_reset_nan_positions_and_complex_input():
    import numpy as np

    from envs.pettingzoo_env import TargetDefenseEnv

    env = TargetDefenseEnv()
    still = {agent: np.zeros(2) for agent in env.possible_agents}
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(still)
    positions = np.array([[2.0, 0, 0], [0, 2.0, 0], [0, 2.2, 0]])
    for bad in (np.where(np.eye(3, dtype=bool), np.nan, positions), positions + 1j, positions[:2]):
        with pytest.raises(ValueError, match="positions"):
            env.reset(options={"positions": bad})
    env.reset(options={"positions": positions})
    with pytest.raises(ValueError, match="complex"):
        env.step({**still, "defender": np.array([0.5 + 0.5j, 0.0])})
    _, rewards, terminations, _, _ = env.step(still)  # the refused steps left the game untouched
    assert not any(terminations.values()) and set(rewards) == set(env.possible_agents)


def test_a_keyboard_interrupt_from_inside_a_library_is_a_stop_not_a_traceback(tiny_config, tmp_path, monkeypatch, capsys):
    # Ctrl-C during the final evaluation can surface as the KeyboardInterrupt of `ray.get`
    # rather than the run's own `Stopped`: the same one line and exit code all the same.
    from types import SimpleNamespace

    class Coordinator:
        def __init__(self, run_dir):
            self.store = LeagueStore(run_dir, create=True)
            self.state = SimpleNamespace(iteration=0)

        def train(self, progress, stop):
            pass

    def finish(coordinator, progress, stop):
        raise KeyboardInterrupt

    run_dir = tmp_path / "new"
    monkeypatch.setattr(run, "start_ray", lambda *args: None)
    monkeypatch.setattr(run, "finish", finish)
    monkeypatch.setattr(run, "new_run", lambda config, directory, stop: Coordinator(directory))
    try:
        code = run.main(["--config", tiny_config(), "--run-dir", str(run_dir)])
    except KeyboardInterrupt:
        pytest.fail("the KeyboardInterrupt escaped main()")
    assert code == 130
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert err.strip().splitlines()[-1] == (
        f"stopped at iteration 0, last checkpoint none, resume with `python -m league.run --resume {run_dir.resolve()}`"
    )


def test_resuming_a_finished_run_says_so_without_starting_ray(run_copy, monkeypatch, capsys):
    def no_ray(*args):
        raise AssertionError("Ray was started for a finished run")

    monkeypatch.setattr(run, "start_ray", no_ray)
    before = query(run_copy, "SELECT * FROM iterations ORDER BY iteration")
    assert run.main(["--resume", str(run_copy)]) == 0
    assert "is finished" in capsys.readouterr().out
    assert query(run_copy, "SELECT * FROM iterations ORDER BY iteration") == before


def test_status_and_evaluate_give_their_numbers_as_json(run_copy, capsys):
    import json

    from league.core.payoff import aggregate, player_record

    assert status.main(["--run-dir", str(run_copy), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    store = LeagueStore(run_copy)
    payoff = aggregate(store.counted_results())
    players = {p.name: p for p in store.players()}
    assert data["finished"] is True and data["iteration"] == store.last_iteration()["iteration"]
    assert {row["player"] for row in data["players"]} == set(players)
    for row in data["players"]:
        wins, games = player_record(payoff, players[row["player"]].side, players[row["player"]].id)
        assert (row["wins"], row["games"]) == (wins, games)
    store.close()
    weights = {side: sum(p["nash_weight"] for p in data["meta_game"]["players"] if p["side"] == side) for side in ("attacker", "team")}
    assert weights == pytest.approx({"attacker": 1.0, "team": 1.0})

    assert evaluate.main(["--run-dir", str(run_copy), "--episodes", "4", "--workers", "0", "--json"]) == 0
    evaluated = json.loads(capsys.readouterr().out)
    recorded = query(run_copy, "SELECT attacker, team, SUM(count) FROM matches WHERE source = 'evaluation' "
                               "AND outcome IN ('captured', 'timeout') GROUP BY attacker, team")
    by_id = {p.id: p.name for p in players.values()}
    wins = {(by_id[a], by_id[t]): n for a, t, n in recorded}
    for pair in evaluated["pairs"]:
        assert pair["games"] == 4 == sum(pair["outcomes"].values())
        assert pair["attacker_wins"] == wins.get((pair["attacker"], pair["team"]), 0)



def check_nash_groups(meta_json: dict, payoff: dict, players: list) -> None:
    """``meta_json["groups"]`` (``--json``) against the Nash ranges of its payoff matrix solved here."""
    import numpy as np

    from league.analysis.nash import meta_game_players, weight_range

    attackers, teams = meta_game_players(players)
    matrix = np.array([[payoff[(a.id, t.id)][0] / payoff[(a.id, t.id)][1] for t in teams] for a in attackers])
    weights = {(p["side"], p["player"]): p["nash_weight"] for p in meta_json["players"]}
    groups = meta_json["groups"]
    assert [(g["side"], g["group"]) for g in groups] == [
        (side, group) for side in ("attacker", "team") for group in ("learners", "exploiters", "oracles", "scripted_and_v0")]
    for side, chosen in (("attacker", attackers), ("team", teams)):
        expected = {
            "learners": [p.name for p in chosen if p.kind == "snapshot" and p.version > 0],
            "exploiters": [p.name for p in chosen if p.kind == "exploiter_snapshot"],
            "oracles": [p.name for p in chosen if p.kind == "oracle"],
            "scripted_and_v0": [p.name for p in chosen
                                if p.kind == "scripted" or (p.kind == "snapshot" and p.version == 0)],
        }
        for g in (g for g in groups if g["side"] == side):
            assert g["players"] == expected[g["group"]]
            assert g["vertex_weight"] == pytest.approx(sum(weights[(side, name)] for name in g["players"]))
            members = [k for k, p in enumerate(chosen) if p.name in g["players"]]
            ends = weight_range(matrix, "row" if side == "attacker" else "column", members) if members else (0.0, 0.0)
            assert g["range"] == pytest.approx(list(ends), abs=1e-9)
            assert g["range"][0] - 1e-5 <= g["vertex_weight"] <= g["range"][1] + 1e-5


def test_status_and_evaluate_give_each_groups_nash_range_beside_the_vertex(run_copy, capsys):
    import json

    from league.core.payoff import aggregate

    assert status.main(["--run-dir", str(run_copy)]) == 0
    out = capsys.readouterr().out
    assert "Nash weight by group" in out and "range over optimal mixtures" in out and "one optimal vertex" in out
    assert status.main(["--run-dir", str(run_copy), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    store = LeagueStore(run_copy)
    players, payoff = store.players(), aggregate(store.newest_evaluation_rows())
    store.close()
    check_nash_groups(data["meta_game"], payoff, players)

    assert evaluate.main(["--run-dir", str(run_copy), "--episodes", "4", "--workers", "0", "--json"]) == 0
    evaluated = json.loads(capsys.readouterr().out)
    by_name = {p.name: p.id for p in players}
    played = {(by_name[r["attacker"]], by_name[r["team"]]): (r["attacker_wins"], r["games"])
              for r in evaluated["pairs"]}
    check_nash_groups(evaluated["meta_game"], played, players)


def test_set_is_explained_in_the_help(capsys):
    with pytest.raises(SystemExit):
        run.parse_args(["--help"])
    assert "override a config key" in " ".join(capsys.readouterr().out.split())


def test_a_run_made_before_a_key_existed_resumes_with_its_default_and_not_with_another_value(run_copy):
    from league.config import config_hash
    from league.state.run_dir import CONFIG_HASH_META, CONFIG_META, RunDirError, check_config_unchanged, read_config

    store = LeagueStore(run_copy)
    older = store.get_meta(CONFIG_META)
    del older["ppo"]["bf16"]  # as a version without `ppo.bf16` recorded it
    with store.transaction():
        store.set_meta(CONFIG_META, older)
        store.set_meta(CONFIG_HASH_META, "the older version's hash")
    run_config = read_config(run_copy)
    check_config_unchanged(run_copy, run_config, store)  # the key at its default: the run as it was
    with_bf16 = run_config.model_copy(update={"ppo": run_config.ppo.model_copy(update={"bf16": True})})
    assert config_hash(with_bf16) != config_hash(run_config)
    with pytest.raises(RunDirError, match=r"was changed after the run started \(ppo.bf16\)"):
        check_config_unchanged(run_copy, with_bf16, store)


def test_a_restored_database_says_what_it_lost_and_names_the_weights_it_does_not_know(run_copy):
    from league.state.run_dir import restore_damaged_database

    store = LeagueStore(run_copy)
    [newest, *_] = sorted(store.checkpoints(), reverse=True)
    known = sorted(p.name for p in store.players() if (run_copy / "players" / p.name).is_dir())  # kept unnamed
    store.close()
    # What league.exploit leaves after the newest checkpoint: a best response's weights (its row is in
    # the database that is damaged below, not in the checkpoint's copy).
    shutil.copytree(run_copy / "players" / known[0], run_copy / "players" / "attacker-m2-br0")
    truncate(run_copy / "league.db")
    said = restore_damaged_database(run_copy).splitlines()
    assert said[0].endswith(f"restored it from {newest[1]}/league.db, the copy kept with that checkpoint")
    assert said[1].startswith(f"warning: everything recorded after the checkpoint of iteration {newest[0]} is lost")
    assert "league.exploit" in said[1]
    assert said[2].startswith("warning: 1 saved player(s) the restored league.db does not know")
    assert said[2].split("checkpoint: ")[1].split(" (")[0].split(", ") == ["players/attacker-m2-br0"]

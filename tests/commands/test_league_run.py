"""``league.run``: end-to-end league runs in subprocesses (each starts and stops its own Ray), and
its exits on bad input."""

import re
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from envs.scripted import PLAYERS
from league.run import main as run_main
from tests.test_config import write

# Every scripted team the game has (each scripted targeter with each scripted defender).
EVERY_SCRIPTED_TEAM = "".join(
    f"\n    - {{targeter: {t}, defender: {d}}}" for t in PLAYERS["targeter"] for d in PLAYERS["defender"]
)
TINY = """
name: tiny
seed: 1
game: {{terminal_reward: 1.0}}
ppo: {{train_batch_size: 200, minibatch_size: 100, num_epochs: 1, hidden: [16]}}
resources: {{num_cpus: 2, num_env_runners: 0, num_envs_per_env_runner: 4}}
league:
  mode: selfplay
  selfplay_phases: {phases}
  min_phase_episodes: 100000
  phase_env_steps: {phase_steps}
  scripted_teams:{every_team}
evaluation: {{episodes: 20}}
checkpoint_every: 1
"""
RUN_TIMEOUT = 600


def league(*args, **kwargs):
    return subprocess.Popen(
        [sys.executable, "-m", "league.run", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,  # its own process group: the kill below reaches only this run
        **kwargs,
    )


def query(run_dir: Path, sql: str):
    with sqlite3.connect(run_dir / "league.db", timeout=30) as db:
        return db.execute(sql).fetchall()


def finish(proc) -> str:
    out, _ = proc.communicate(timeout=RUN_TIMEOUT)
    assert proc.returncode == 0, out[-3000:]
    return out


@pytest.fixture
def tiny_config(tmp_path):
    def make(phases, phase_steps):
        path = tmp_path / f"tiny_{phases}_{phase_steps}.yaml"
        path.write_text(TINY.format(phases=phases, phase_steps=phase_steps, every_team=EVERY_SCRIPTED_TEAM))
        return str(path)

    return make


def test_a_run_snapshots_grows_the_league_and_evaluates(tmp_path, tiny_config):
    run_dir = tmp_path / "run"
    # The attackers' games all for the scripted teams, evenly, so that all twelve meet them in this short run.
    out = finish(league("--config", tiny_config(3, 1000), "--run-dir", str(run_dir), "--set", "league.scripted_share={attacker: 1.0}",
                        "--set", "league.scripted_weighting=uniform"))
    snapshots = query(run_dir, "SELECT side, version, checkpoint FROM players WHERE kind = 'snapshot' ORDER BY id")
    # v0 of both sides at the start, then one snapshot per phase: attacker, team, attacker.
    assert [(s, v) for s, v, _ in snapshots] == [("attacker", 0), ("team", 0), ("attacker", 1), ("team", 1), ("attacker", 2)]
    assert all((run_dir / path / "module_state.pkl").exists() for _, _, path in snapshots)
    phases = query(run_dir, "SELECT DISTINCT phase, learner_side FROM iterations ORDER BY phase")
    assert phases == [(0, "attacker"), (1, "team"), (2, "attacker")]
    assert query(run_dir, "SELECT COUNT(*) FROM matches WHERE source = 'training'")[0][0] > 0
    # A phase starts with new games: no training game of a learner outside its own phases,
    # and each learner's env steps end where its last snapshot was taken.
    stray = query(run_dir, """
        SELECT COUNT(*) FROM matches m JOIN iterations i ON i.iteration = m.iteration
        JOIN players a ON a.id = m.attacker JOIN players t ON t.id = m.team
        WHERE m.source = 'training'
          AND ((a.kind = 'learner' AND i.learner_side = 'team') OR (t.kind = 'learner' AND i.learner_side = 'attacker'))""")
    assert stray == [(0,)]
    steps = query(run_dir, """
        SELECT l.env_steps, (SELECT s.env_steps FROM players s WHERE s.parent = l.id ORDER BY s.version DESC LIMIT 1)
        FROM players l WHERE l.kind = 'learner'""")
    assert all(learner == snapshot for learner, snapshot in steps), steps
    # Every scripted team combination is in the attackers' pool: a player, trained against, evaluated.
    scripted_teams = query(run_dir, "SELECT id FROM players WHERE side = 'team' AND kind = 'scripted'")
    assert len(scripted_teams) == len(PLAYERS["targeter"]) * len(PLAYERS["defender"])
    trained_against = query(run_dir, """
        SELECT DISTINCT m.team FROM matches m JOIN players t ON t.id = m.team
        WHERE m.source = 'training' AND t.kind = 'scripted'""")
    assert sorted(trained_against) == sorted(scripted_teams)
    assert query(run_dir, "SELECT COUNT(DISTINCT attacker || '-' || team) FROM matches WHERE source = 'evaluation'")[0][0] == 4 * (len(scripted_teams) + 2)  # attackers: scripted, v0-v2; teams: the scripted ones, v0, v1
    assert (run_dir / "evaluation.md").read_text().count("\n| ") >= 24
    assert list((run_dir / "tensorboard").glob("events.out.tfevents.*"))
    last_checkpoint = query(run_dir, "SELECT path FROM checkpoints ORDER BY iteration DESC LIMIT 1")[0][0]
    assert (run_dir / last_checkpoint / "rllib_checkpoint.json").exists()
    assert "steps/s" in out and "snapshot attacker-m2-v2" in out
    # The last line splits the run's time: training iterations, evaluations during training,
    # the final evaluation and the rest, which add up to the whole.
    done = re.search(r"done in (\d+) s \(training iterations (\d+) s \(\d+%\), evaluations during training (\d+) s "
                     r"\(\d+%\), final evaluation (\d+) s \(\d+%\), the rest (\d+) s \(\d+%\)\)", out)
    assert done, out[-2000:]
    total, *parts = (int(seconds) for seconds in done.groups())
    # Five numbers, each rounded to the second: a fast CPU trains this tiny run's iterations in
    # under half a second, so no part is sure to be above 0.
    assert abs(sum(parts) - total) <= 3
    assert "new API stack" not in out and "already in registry" not in out and "\x1b[" not in out  # no library banners

    status = subprocess.run(
        [sys.executable, "-m", "league.status", "--run-dir", str(run_dir)], capture_output=True, text=True, check=True
    )
    assert "attacker-m2-v2" in status.stdout and "scripted-lead_intercept" in status.stdout and "rating" in status.stdout


def test_existing_run_dir_is_refused(tmp_path, tiny_config):
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "league.db").write_text("")
    proc = subprocess.run(
        [sys.executable, "-m", "league.run", "--config", tiny_config(1, 200), "--run-dir", str(run_dir)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2 and "--resume" in proc.stderr


def test_remote_env_runners_holding_every_cpu_do_not_hang_the_final_evaluation(tmp_path, tiny_config):
    # 2 env runners of 1 CPU each take both CPUs of the run's Ray instance; its 2 evaluation
    # workers (0.5 CPU each) can start only once the algorithm has stopped.
    run_dir = tmp_path / "run"
    out = finish(league(
        "--config", tiny_config(1, 400), "--run-dir", str(run_dir),
        "--set", "resources.num_env_runners=2", "--set", "resources.num_cpus_per_env_runner=1",
        "--set", "evaluation.workers=2",
    ))
    assert "evaluation of" in out and "evaluating in the driver" not in out
    assert query(run_dir, "SELECT COUNT(*) FROM matches WHERE source = 'evaluation'")[0][0] > 0


def test_evaluate_on_workers_prints_no_ray_banners(tiny_run, tmp_path):
    import shutil

    run_dir = tmp_path / "run"
    shutil.copytree(tiny_run, run_dir)
    proc = subprocess.run(
        [sys.executable, "-m", "league.evaluate", "--run-dir", str(run_dir), "--workers", "2", "--episodes", "4"],
        capture_output=True, text=True, timeout=RUN_TIMEOUT,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "fixed dev games of scenario set" in proc.stdout
    assert "Token authentication" not in proc.stderr and "Started a local Ray instance" not in proc.stderr, proc.stderr


def test_run_exits_2_on_bad_config_and_writes_nothing(tmp_path, capsys):
    run_dir = tmp_path / "run"
    assert run_main(["--config", write(tmp_path, "name: x\nppo: {bogus: 1}\n"), "--run-dir", str(run_dir)]) == 2
    assert "ppo.bogus" in capsys.readouterr().err
    assert not run_dir.exists()
    assert run_main(["--config", "smoke", "--run-dir", str(run_dir), "--set", "league.pfsp=best"]) == 2
    assert "league.pfsp" in capsys.readouterr().err and not run_dir.exists()


def test_resume_of_a_non_run_exits_2(tmp_path, capsys):
    assert run_main(["--resume", str(tmp_path)]) == 2
    assert "not a league run directory" in capsys.readouterr().err

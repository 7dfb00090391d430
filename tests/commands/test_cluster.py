"""``league.run --address``: a two-node Ray cluster made with ``ray start`` on this machine, and
addresses where no cluster answers.

The cluster (``bench/local_cluster.py``) is what ``docs/operations.md`` makes: a head and a
worker node, each started by ``ray start`` with one ``sampler`` and one ``evaluator``, on
free ports and a temporary directory of its own, token auth on (``RAY_AUTH_MODE=token``
and the cluster's token on both nodes). The run is started as a user would after a local
``ray.init`` wrote a token: ``RAY_AUTH_MODE`` unset, the token at hand. The test stops only
the nodes it started, by pid.
"""

import os
import signal
import socket
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
from local_cluster import LocalCluster, free_port  # noqa: E402

CONFIG = """
name: cluster-test
seed: 2
ppo: {train_batch_size: 400, minibatch_size: 400, num_epochs: 1, hidden: [16]}
resources:
  num_env_runners: 2
  num_envs_per_env_runner: 8
  num_cpus_per_env_runner: 1
  custom_resources_per_env_runner: {sampler: 1}
# 48 iterations: the run still trains when the test, after listing the actors (seconds), kills a node.
league: {mode: selfplay, selfplay_phases: 2, min_phase_episodes: 100000, phase_env_steps: 9600}
evaluation:
  episodes: 20
  workers: 2
  cpus_per_worker: 0.5
  custom_resources_per_worker: {evaluator: 1}
  every_iterations: 1
  curve_every_env_steps: 0
checkpoint_every: 1
"""
NODE = {"num_cpus": 2, "resources": {"sampler": 1, "evaluator": 1}}


def iterations(run_dir: Path) -> list[int]:
    """Committed iterations; none while the run has not created its league database yet."""
    if not (run_dir / "league.db").exists():
        return []
    with sqlite3.connect(run_dir / "league.db", timeout=30) as db:
        return [i for (i,) in db.execute("SELECT iteration FROM iterations ORDER BY iteration")]


def league_run(tmp_path: Path, address: str, env: dict, **popen) -> subprocess.Popen:
    config = tmp_path / "cluster.yaml"
    config.write_text(CONFIG)
    command = [sys.executable, "-m", "league.run", "--config", str(config), "--run-dir", str(tmp_path / "run"), "--address", address]
    return subprocess.Popen(command, env=env, text=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, **popen)


def finish(proc: subprocess.Popen, timeout: float) -> str:
    """The process's output once it ended; killed (and the test failed) if it runs past ``timeout``."""
    try:
        return proc.communicate(timeout=timeout)[0]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def driver_env(cluster: LocalCluster) -> dict:
    """A driver's environment where the head's token is at hand but token mode was never asked for."""
    env = dict(cluster.env)
    env.pop("RAY_AUTH_MODE")
    return env


def ask(cluster: LocalCluster, env: dict) -> str:
    """``check_cluster`` of the cluster in a process with ``env``: "joined", or its error after "the Ray cluster at ADDR "."""
    code = (
        "import contextlib, sys\n"
        "from league.cluster import ClusterError, check_cluster\n"
        "try:\n    check_cluster(sys.argv[1], contextlib.nullcontext)\n    print('joined')\n"
        "except ClusterError as err:\n    print(str(err).split(' ', 5)[-1])\n"
    )
    done = subprocess.run([sys.executable, "-c", code, cluster.address], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and not done.stderr, done.stderr[-2000:]
    return done.stdout.strip()


def test_a_run_trains_and_evaluates_on_both_nodes_and_survives_losing_one(tmp_path):
    with LocalCluster() as cluster:
        cluster.add_node(**NODE)
        worker = cluster.add_node(**NODE)
        nodes = cluster.node_ids()
        assert len(nodes) == 2

        # The cluster asks for a token: each case of this machine's settings in its one line.
        mode_unset = driver_env(cluster)
        assert ask(cluster, mode_unset) == "joined"  # the token at hand: token mode turned on
        assert ask(cluster, {**mode_unset, "RAY_AUTH_TOKEN": "0" * 64}).startswith("refused this machine's token")
        assert ask(cluster, {**mode_unset, "RAY_AUTH_MODE": "disabled"}).startswith("asks for a token and RAY_AUTH_MODE=disabled here")
        # No token at all: league.run says where to put it in one line, exit 2, nothing written.
        tokenless = {k: v for k, v in driver_env(cluster).items() if k != "RAY_AUTH_TOKEN"} | {"HOME": str(tmp_path)}
        refused = subprocess.run(
            [sys.executable, "-m", "league.run", "--config", "smoke", "--run-dir", str(tmp_path / "refused"), "--address", cluster.address],
            env=tokenless, capture_output=True, text=True, timeout=300,
        )
        assert refused.returncode == 2, refused.stdout[-2000:] + refused.stderr[-2000:]
        [line] = refused.stderr.strip().splitlines()
        assert line.startswith("error: the Ray cluster at ") and "asks for a token and this machine has none" in line, line
        assert not (tmp_path / "refused").exists()

        run_dir = tmp_path / "run"
        proc = league_run(tmp_path, cluster.address, driver_env(cluster))
        try:
            deadline = time.monotonic() + 300
            while len(iterations(run_dir)) < 2 and proc.poll() is None and time.monotonic() < deadline:
                time.sleep(0.5)
            assert proc.poll() is None, proc.communicate()[0][-3000:]
            # Trained and evaluated on both nodes: one env runner and one evaluation worker on each.
            runners = cluster.actors("BatchedEnvRunner")
            evaluators = cluster.actors("EvaluationWorker")
            cluster.kill(worker)  # its env runner and evaluation worker die with it
            output, _ = proc.communicate(timeout=600)
        finally:
            if proc.poll() is None:
                proc.kill()
    assert sorted(actor["node_id"] for actor in runners) == nodes
    assert sorted(actor["node_id"] for actor in evaluators) == nodes
    assert proc.returncode == 0, output[-3000:]
    # The loss: said in a line or two, without Ray's and RLlib's error dumps.
    assert "lost 1 of 2 env runners" in output, output[-3000:]
    assert "evaluation worker lost" in output, output[-3000:]
    assert "actor_manager" not in output and "state-dump" not in output and "Traceback" not in output, output[-3000:]
    # The run complete and intact.
    done = iterations(run_dir)
    assert done == list(range(1, len(done) + 1)) and len(done) >= 6, output[-3000:]
    with sqlite3.connect(run_dir / "league.db") as db:
        assert db.execute("PRAGMA integrity_check").fetchone() == ("ok",)
        evaluated = db.execute("SELECT COUNT(*) FROM matches WHERE source = 'evaluation' AND iteration > ?", (done[-1] - 2,)).fetchone()[0]
        snapshots = db.execute("SELECT COUNT(*) FROM players WHERE kind = 'snapshot' AND version > 0").fetchone()[0]
    assert evaluated > 0 and snapshots == 2
    assert (run_dir / "evaluation.md").exists()


def test_an_address_where_nothing_listens_fails_at_once_in_one_line(tmp_path):
    address = f"127.0.0.1:{free_port()}"
    started = time.monotonic()
    proc = league_run(tmp_path, address, {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"})
    output = finish(proc, 120)
    assert proc.returncode == 2, output[-3000:]
    assert output.strip().splitlines() == [output.strip().splitlines()[0]]
    assert output.startswith(f"error: no Ray cluster at --address {address} ") and "Connection refused" in output
    assert not (tmp_path / "run").exists()
    assert time.monotonic() - started < 120  # the imports take most of it; Ray's own client retried for minutes


@pytest.mark.parametrize("command", [["league.reproduce"], ["league.study", "--config", "smoke", "--seeds", "0", "1"]])
def test_a_study_on_an_address_where_nothing_listens_fails_at_once_in_one_line(tmp_path, command):
    address = f"127.0.0.1:{free_port()}"
    done = subprocess.run([sys.executable, "-m", *command, "--address", address, "--out", str(tmp_path / "out")],
                          env={k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 2, done.stderr[-3000:]
    assert done.stderr.startswith(f"error: no Ray cluster at --address {address} ") and len(done.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_ctrl_c_while_a_silent_address_is_asked_stops_the_run(tmp_path):
    """Something accepts the connection and never answers, as a GCS that hangs would: Ctrl-C
    during the wait stops the run at once, with nothing kept."""
    with socket.socket() as server:
        server.bind(("", 0))  # Ray asks the machine's own address for 127.0.0.1
        server.listen()
        server.settimeout(120)
        address = f"127.0.0.1:{server.getsockname()[1]}"
        proc = league_run(tmp_path, address, {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}, start_new_session=True)
        try:
            connections = [server.accept()[0] for _ in range(2)]  # the address checked, then Ray's client asking
            asked = time.monotonic()
            os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C goes to the foreground process group
        finally:
            output = finish(proc, 60)
        for connection in connections:
            connection.close()
    assert proc.returncode == 130, output[-3000:]
    assert time.monotonic() - asked < 10
    assert output.strip().splitlines()[-1] == f"stopped before the first checkpoint; nothing was kept in {tmp_path / 'run'}"
    assert not (tmp_path / "run").exists()

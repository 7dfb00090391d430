"""The league on a two-node Ray cluster started on this machine (``ray.cluster_utils.Cluster``).

Both nodes declare one ``sampler`` and one ``evaluator`` resource, and the config asks
one of each per env runner and evaluation worker: so each node gets one of each.
"""

import sqlite3
import subprocess
import sys
import time

import pytest
from ray.cluster_utils import Cluster

CONFIG = """
name: cluster-test
seed: 2
ppo: {{train_batch_size: 400, minibatch_size: 200, num_epochs: 1, hidden: [16]}}
resources:
  num_env_runners: 2
  num_envs_per_env_runner: 8
  num_cpus_per_env_runner: 1
  custom_resources_per_env_runner: {{sampler: 1}}
league: {{mode: selfplay, selfplay_phases: 2, min_phase_episodes: 100000, phase_env_steps: {phase_steps}}}
evaluation:
  episodes: 40
  workers: 2
  cpus_per_worker: 0.5
  custom_resources_per_worker: {{evaluator: 1}}
  every_iterations: 1
checkpoint_every: 1
"""
NODE = {"num_cpus": 2, "resources": {"sampler": 1, "evaluator": 1}}


@pytest.fixture
def cluster():
    cluster = Cluster(initialize_head=True, head_node_args={**NODE, "include_dashboard": True})
    worker = cluster.add_node(**NODE)
    cluster.wait_for_nodes()
    yield cluster, worker
    cluster.shutdown()


def start_run(cluster, tmp_path, phase_steps):
    config = tmp_path / "cluster.yaml"
    config.write_text(CONFIG.format(phase_steps=phase_steps))
    run_dir = tmp_path / "run"
    command = [sys.executable, "-m", "league.run", "--config", str(config), "--run-dir", str(run_dir)]
    proc = subprocess.Popen(
        [*command, "--address", cluster.address], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    return proc, run_dir


def iterations(run_dir):
    if not (run_dir / "league.db").exists():
        return []
    with sqlite3.connect(run_dir / "league.db") as db:
        return [i for (i,) in db.execute("SELECT iteration FROM iterations ORDER BY iteration")]


def assert_complete(run_dir, output):
    done = iterations(run_dir)
    assert done == list(range(1, len(done) + 1)) and len(done) >= 4, output[-3000:]
    with sqlite3.connect(run_dir / "league.db") as db:
        checkpoints = [path for (path,) in db.execute("SELECT path FROM checkpoints")]
        evaluated = db.execute("SELECT COUNT(*) FROM matches WHERE source = 'evaluation'").fetchone()[0]
        snapshots = db.execute("SELECT COUNT(*) FROM players WHERE kind = 'snapshot' AND version > 0").fetchone()[0]
    assert checkpoints and all((run_dir / path).is_dir() for path in checkpoints)
    assert evaluated > 0 and snapshots == 2
    assert (run_dir / "evaluation.md").exists()


def nodes_of(class_name, address):
    from ray.util.state import list_actors

    actors = list_actors(address=address, filters=[("class_name", "=", class_name)], limit=1000, detail=True)
    return {actor.node_id for actor in actors}


def test_env_runners_and_evaluation_workers_run_on_both_nodes(cluster, tmp_path):
    cluster, _ = cluster
    proc, run_dir = start_run(cluster, tmp_path, phase_steps=800)
    output, _ = proc.communicate(timeout=600)
    assert proc.returncode == 0, output[-3000:]
    assert_complete(run_dir, output)
    dashboard = cluster.head_node.address_info["webui_url"]
    nodes = {node.node_id for node in cluster.list_all_nodes()}
    assert nodes_of("BatchedEnvRunner", dashboard) == nodes
    assert nodes_of("EvaluationWorker", dashboard) == nodes


def test_losing_a_worker_node_mid_run_does_not_stop_the_run(cluster, tmp_path):
    cluster, worker = cluster
    proc, run_dir = start_run(cluster, tmp_path, phase_steps=2400)
    deadline = time.monotonic() + 300
    while len(iterations(run_dir)) < 2:
        assert proc.poll() is None and time.monotonic() < deadline, proc.stdout.read()[-3000:]
        time.sleep(0.5)
    cluster.remove_node(worker)  # its env runner and evaluation worker die with it
    output, _ = proc.communicate(timeout=600)
    assert proc.returncode == 0, output[-3000:]
    assert "lost 1 of 2 env runners" in output, output[-3000:]
    assert "evaluation worker lost" in output and "replaying evaluation games" in output, output[-3000:]
    assert_complete(run_dir, output)

"""The league on a two-node Ray cluster started on this machine (``ray.cluster_utils.Cluster``).

Both nodes declare one ``sampler`` and one ``evaluator`` resource, and the config asks
one of each per env runner and evaluation worker: so each node gets one of each.

The scenario runs in a child process (this file run as a script): the cluster's nodes
and Ray's state API client live and die there, not in pytest's process. One cluster and one
run serve both checks (the actors spread over both nodes, then the run survives losing one),
since starting a cluster is most of the test's time.
"""

import json
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

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


# ---------------------------------------------------------------- in the child process
def iterations(run_dir):
    """Committed iterations; none while the run has not created its league database yet."""
    if not (run_dir / "league.db").exists():
        return []
    with sqlite3.connect(run_dir / "league.db", timeout=30) as db:
        if not db.execute("SELECT 1 FROM sqlite_master WHERE name = 'iterations'").fetchone():
            return []  # no schema yet, so nothing committed
        return [i for (i,) in db.execute("SELECT iteration FROM iterations ORDER BY iteration")]


def scenario(tmp_path):
    """Start the cluster, run the league on it, see where its actors run, then lose the worker node."""
    from ray.cluster_utils import Cluster
    from ray.util.state import list_actors

    cluster = Cluster(initialize_head=True, head_node_args={**NODE, "include_dashboard": True})
    try:
        worker = cluster.add_node(**NODE)
        cluster.wait_for_nodes()
        nodes = sorted(node.node_id for node in cluster.list_all_nodes())
        config = tmp_path / "cluster.yaml"
        config.write_text(CONFIG.format(phase_steps=2400))
        run_dir = tmp_path / "run"
        command = [sys.executable, "-m", "league.run", "--config", str(config), "--run-dir", str(run_dir)]
        proc = subprocess.Popen(
            [*command, "--address", cluster.address], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
        )

        def nodes_of(class_name):
            actors = list_actors(address=cluster.address, filters=[("class_name", "=", class_name)], limit=1000, detail=True)
            return sorted({actor.node_id for actor in actors})

        # Two committed iterations: the env runners sampled and the evaluation workers evaluated.
        deadline = time.monotonic() + 300
        while len(iterations(run_dir)) < 2 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.5)
        placed = {"env_runner_nodes": nodes_of("BatchedEnvRunner"), "evaluation_worker_nodes": nodes_of("EvaluationWorker")}
        cluster.remove_node(worker)  # its env runner and evaluation worker die with it
        output, _ = proc.communicate(timeout=600)
        return {"returncode": proc.returncode, "output": output, "run_dir": str(run_dir), "nodes": nodes, **placed}
    finally:
        cluster.shutdown()


# ---------------------------------------------------------------- in pytest's process
def test_a_run_spreads_over_both_nodes_and_losing_one_does_not_stop_it(tmp_path):
    proc = subprocess.run([sys.executable, __file__, str(tmp_path)], capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    output = result["output"]
    assert result["returncode"] == 0, output[-3000:]
    # Before the loss: one env runner and one evaluation worker on each node.
    assert len(result["nodes"]) == 2
    assert result["env_runner_nodes"] == result["nodes"]
    assert result["evaluation_worker_nodes"] == result["nodes"]
    # The loss: told, replaced, and the run complete.
    assert "lost 1 of 2 env runners" in output, output[-3000:]
    assert "evaluation worker lost" in output and "replaying evaluation games" in output, output[-3000:]
    run_dir = Path(result["run_dir"])
    done = iterations(run_dir)
    assert done == list(range(1, len(done) + 1)) and len(done) >= 4, output[-3000:]
    with sqlite3.connect(run_dir / "league.db") as db:
        checkpoints = [path for (path,) in db.execute("SELECT path FROM checkpoints")]
        evaluated = db.execute("SELECT COUNT(*) FROM matches WHERE source = 'evaluation'").fetchone()[0]
        snapshots = db.execute("SELECT COUNT(*) FROM players WHERE kind = 'snapshot' AND version > 0").fetchone()[0]
    assert checkpoints and (run_dir / checkpoints[-1]).is_dir()  # the newest ones are kept on disk
    assert evaluated > 0 and snapshots == 2
    assert (run_dir / "evaluation.md").exists()


if __name__ == "__main__":
    print(json.dumps(scenario(Path(sys.argv[1]))))

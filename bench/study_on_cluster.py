"""A study spread over a Ray cluster: ``python bench/study_on_cluster.py``.

Starts a two-node Ray cluster on this machine (``ray.cluster_utils.Cluster``, one CPU per
node), runs ``league.reproduce --address`` on it with two tiny runs of one CPU each, so each
node can hold only one, and checks from the nodes ``league.reproduce`` prints that the runs
trained on both. The cluster lives and dies in this process; nothing else is stopped.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
from pathlib import Path

TINY = [
    "ppo.train_batch_size=512", "ppo.minibatch_size=256", "ppo.num_epochs=1", "ppo.hidden=[16]",
    "resources.num_envs_per_env_runner=16", "evaluation.workers=0", "evaluation.curve_every_env_steps=0",
]


def main() -> int:
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
    try:
        cluster.add_node(num_cpus=1)
        cluster.wait_for_nodes()
        nodes = {node.node_id for node in cluster.list_all_nodes()}
        with tempfile.TemporaryDirectory() as out:
            command = [sys.executable, "-m", "league.reproduce", "--address", cluster.address, "--cpus-per-run", "1",
                       "--seeds", "2", "--methods", "2", "--env-steps", "1000", "--evaluation-episodes", "20",
                       "--out", out, *[item for o in TINY for item in ("--set", o)]]
            print("$", " ".join(command[1:]), flush=True)
            done = subprocess.run(command, capture_output=True, text=True)
            print(done.stdout[-3000:], done.stderr[-3000:], sep="\n")
            if done.returncode:
                return done.returncode
            used = set(re.findall(r"trained on node (\w+)", done.stdout))
            runs = sorted(Path(out).glob("paper/*/method2-seed*/evaluation.md"))
            print(f"{len(runs)} runs finished on {len(used)} of the cluster's {len(nodes)} nodes")
            return 0 if used == nodes and len(runs) == 2 else 1
    finally:
        cluster.shutdown()


if __name__ == "__main__":
    sys.exit(main())

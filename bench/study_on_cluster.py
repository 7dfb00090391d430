"""A study spread over a Ray cluster: ``python bench/study_on_cluster.py``.

Starts a two-node cluster of ``ray start`` nodes on this machine (``bench/local_cluster.py``:
free ports, its own temporary directory and token, one CPU per node), runs ``league.study
--address`` on it with two tiny runs of one CPU each (``--cpus-per-run 1``), so each node can
hold only one, prints the node each run trained on (the study's ``trained on node`` lines)
and checks that the runs used both nodes. Then runs the same command again, which restores
the Tune experiment and trains nothing. Stops only the nodes it started, by pid.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from local_cluster import LocalCluster

TINY = [
    "ppo.train_batch_size=512", "ppo.minibatch_size=256", "ppo.num_epochs=1", "ppo.hidden=[16]",
    "resources.num_cpus=1", "resources.num_envs_per_env_runner=16", "league.selfplay_phases=2",
    "league.phase_env_steps=1024", "league.min_phase_episodes=100000", "evaluation.episodes=20",
    "evaluation.curve_every_env_steps=0",
]


def study(cluster: LocalCluster, out: str) -> tuple[subprocess.CompletedProcess, float]:
    """``league.study --address`` of two seeds of the smoke config cut down to ``TINY``; its wall time."""
    command = [sys.executable, "-m", "league.study", "--config", "smoke", "--seeds", "0", "1", "--episodes", "20",
               "--address", cluster.address, "--cpus-per-run", "1", "--out", out,
               *[item for o in TINY for item in ("--set", o)]]
    print("$", " ".join(command[1:]), flush=True)
    started = time.monotonic()
    done = subprocess.run(command, capture_output=True, text=True, env=cluster.env)
    return done, time.monotonic() - started


def main() -> int:
    with LocalCluster() as cluster, tempfile.TemporaryDirectory() as out:
        cluster.add_node(num_cpus=1)
        cluster.add_node(num_cpus=1)
        nodes = cluster.node_ids()
        print(f"cluster at {cluster.address}: nodes {', '.join(nodes)}")
        done, wall = study(cluster, out)
        lines = [line for line in done.stdout.splitlines() if line.startswith(("study:", "training", "resuming", "reusing"))
                 or "trained on node" in line]
        print("\n".join(lines), done.stderr[-3000:], sep="\n")
        if done.returncode:
            return done.returncode
        used = set(re.findall(r"trained on node (\w+)", done.stdout))
        finished = sorted(Path(out).glob("smoke/seed-*/evaluation.md"))
        print(f"{len(finished)} runs finished on {len(used)} of the cluster's {len(nodes)} nodes in {wall:.0f} s")
        again, wall_again = study(cluster, out)
        first = again.stdout.splitlines()[0] if again.stdout else again.stderr[-3000:]
        print(f"{first}\nagain: exit {again.returncode} in {wall_again:.0f} s")
        trained_again = any(line.startswith(("training ", "resuming ")) for line in again.stdout.splitlines())
        return 0 if used == set(nodes) and len(finished) == 2 and again.returncode == 0 and not trained_again else 1


if __name__ == "__main__":
    sys.exit(main())

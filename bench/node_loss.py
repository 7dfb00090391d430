"""Speed of a run before and after it loses one node of two: ``python bench/node_loss.py``.

Starts a two-node Ray cluster on this machine with ``ray start`` (``bench/local_cluster.py``:
private ports and temporary directory, token auth on), each node with one ``sampler`` and
one ``evaluator``, and trains a small self-play league on it with ``league.run --address``:
two env runners and two evaluation workers, one of each per node. After ``--kill-after``
iterations it kills the worker node (SIGKILL to its ``ray start``, whose Ray processes die
with it); with ``--return-after N`` a fresh node joins N iterations after the loss.

Prints the median env steps/s and sampling seconds of the iterations before the loss and
after it (the iteration of the loss left out: its samples on the lost node are dropped),
their ratio, the run's lines about the loss, and the machine's load average. The target
is a ratio of at least 0.5: the surviving runner samples the whole batch, so each iteration
takes up to twice as long, but it must not wait on the lost one. Exit code 1 if the run
failed or the ratio is under 0.5.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from local_cluster import LocalCluster  # noqa: E402

CONFIG = """
name: node-loss
seed: 4
ppo: {{train_batch_size: {batch}, minibatch_size: {batch}, num_epochs: 1, hidden: [32]}}
resources:
  num_env_runners: 2
  num_envs_per_env_runner: 32
  num_cpus_per_env_runner: 1
  custom_resources_per_env_runner: {{sampler: 1}}
league: {{mode: selfplay, selfplay_phases: 2, min_phase_episodes: 100000, phase_env_steps: {phase_steps}}}
evaluation:
  episodes: 20
  workers: 2
  cpus_per_worker: 0.5
  custom_resources_per_worker: {{evaluator: 1}}
  every_iterations: {evaluate_every}
  curve_every_env_steps: 0
checkpoint_every: 1000
"""
NODE = {"num_cpus": 2, "resources": {"sampler": 1, "evaluator": 1}}
ITERATION = re.compile(r"\| iter +(\d+) \|.*\| +([\d.]+) steps/s \| sample ([\d.]+) s")
LOSS = re.compile(r"lost \d+ of \d+ env runners in iteration (\d+)")


def iterations(log: Path) -> dict[int, tuple[float, float]]:
    """Iteration -> (env steps/s, sampling seconds), from the run's progress lines."""
    text = log.read_text() if log.exists() else ""
    return {int(m[1]): (float(m[2]), float(m[3])) for m in ITERATION.finditer(text)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=24, help="iterations of the run (two phases)")
    parser.add_argument("--kill-after", type=int, default=8, help="iterations before the worker node is killed")
    parser.add_argument("--return-after", type=int, default=0, help="iterations after the loss before a new node joins (0: none)")
    parser.add_argument("--batch", type=int, default=2048, help="env steps per iteration")
    parser.add_argument("--evaluate-every", type=int, default=4)
    args = parser.parse_args()

    with LocalCluster() as cluster, tempfile.TemporaryDirectory() as out:
        cluster.add_node(**NODE)
        worker = cluster.add_node(**NODE)
        config = Path(out) / "node_loss.yaml"
        config.write_text(CONFIG.format(
            batch=args.batch, phase_steps=args.batch * args.iterations // 2, evaluate_every=args.evaluate_every,
        ))
        run_dir = Path(out) / "run"
        command = [sys.executable, "-m", "league.run", "--config", str(config), "--run-dir", str(run_dir), "--address", cluster.address]
        print("$", " ".join(command[1:]), flush=True)
        output = Path(out) / "output.txt"
        started = time.monotonic()
        with open(output, "w") as sink:
            run = subprocess.Popen(command, stdout=sink, stderr=subprocess.STDOUT, env=cluster.env)
            log = run_dir / "run.log"
            while run.poll() is None and len(iterations(log)) < args.kill_after:
                time.sleep(0.5)
            cluster.kill(worker)
            killed_at = max(iterations(log), default=0)
            print(f"killed the worker node after iteration {killed_at} ({time.monotonic() - started:.0f} s)", flush=True)
            if args.return_after:
                while run.poll() is None and max(iterations(log), default=0) < killed_at + 1 + args.return_after:
                    time.sleep(0.5)
                cluster.add_node(**NODE)
                print(f"a new node joined after iteration {max(iterations(log), default=0)}", flush=True)
            run.wait()
        text = output.read_text()
        done = iterations(log)
        lost = [int(i) for i in LOSS.findall(text)]
        print(f"exit {run.returncode} after {time.monotonic() - started:.0f} s; {len(done)} iterations; "
              f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
        print("the run's lines on the loss:")
        for line in text.splitlines():
            if any(k in line for k in ("lost", "back to", "evaluation worker", "replaying", "error", "Error")):
                print("   ", line[:300])
        noise = [line for line in text.splitlines() if not re.match(r"\d\d:\d\d:\d\d ", line)]
        print(f"lines of other output (Ray's logs, tracebacks): {len(noise)}")
        for line in noise:
            print("   ", line[:200])
        if run.returncode or not lost:
            print(text[-3000:])
            return 1
        loss = lost[0]
        before = [done[i] for i in sorted(done) if 1 < i < loss]  # the first iteration warms up
        after = [done[i] for i in sorted(done) if i > loss]
        if args.return_after:
            after = after[: args.return_after]
        speed_before = statistics.median(s for s, _ in before)
        speed_after = statistics.median(s for s, _ in after)
        print(f"before the loss (iterations 2..{loss - 1}): median {speed_before:,.0f} env steps/s, "
              f"sampling {statistics.median(t for _, t in before):.2f} s an iteration")
        print(f"after it ({len(after)} iterations): median {speed_after:,.0f} env steps/s, "
              f"sampling {statistics.median(t for _, t in after):.2f} s an iteration")
        print(f"ratio {speed_after / speed_before:.2f} (target at least 0.5)")
        return 0 if speed_after >= 0.5 * speed_before else 1


if __name__ == "__main__":
    sys.exit(main())

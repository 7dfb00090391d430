"""A Ray cluster of ``ray start`` nodes on this machine, as ``docs/operations.md`` makes one.

Each node is a ``ray start --block`` process (the head first, then workers joining it) on
free ports, with a temporary directory of the cluster's own, so it collides with no other
Ray instance on the machine. Stopping touches only what this cluster started: each node's
``ray start`` process by its pid (SIGKILL: that node's Ray processes die with it), then any
process left whose command line names the cluster's temporary directory. Never ``ray
stop``, which stops every Ray instance of the machine.

Token authentication: every node and every driver gets ``RAY_AUTH_MODE=token`` and the
cluster's own token (``RAY_AUTH_TOKEN``) through ``env``, as the recipe asks; a driver
started with ``cluster.env`` joins it.

Used by ``tests/commands/test_cluster.py``, ``bench/node_loss.py`` and ``bench/study_on_cluster.py``.
"""

from __future__ import annotations

import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

RAY = str(Path(sys.executable).with_name("ray"))
NODE_START_S = 120.0  # a loaded 2-core machine takes tens of seconds to start a node


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class Node:
    process: subprocess.Popen
    log: Path

    @property
    def pid(self) -> int:
        return self.process.pid


class LocalCluster:
    """``with LocalCluster() as cluster: cluster.add_node(...)``; the first node added is the head."""

    def __init__(self) -> None:
        # Short: Ray's socket paths under it must stay under the 107 characters of a Unix socket name.
        self.temp_dir = Path(tempfile.mkdtemp(prefix="rc-", dir="/tmp"))
        self.token = secrets.token_hex(32)
        self.env = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": self.token}
        self.env.pop("RAY_ADDRESS", None)
        self.port = free_port()
        self.address = f"127.0.0.1:{self.port}"
        self.dashboard_port = free_port()
        self.nodes: list[Node] = []

    def __enter__(self) -> LocalCluster:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def add_node(self, num_cpus: float, resources: dict[str, float] | None = None) -> Node:
        """Start a node (the head if it is the first) and wait until ``ray start`` says it runs."""
        head = not self.nodes
        ports = {
            "--node-manager-port": free_port(), "--object-manager-port": free_port(),
            "--dashboard-agent-listen-port": free_port(), "--dashboard-agent-grpc-port": free_port(),
            "--runtime-env-agent-port": free_port(), "--metrics-export-port": free_port(),
            "--min-worker-port": 0, "--max-worker-port": 0,  # 0: any free port
        }
        if head:
            ports.update({
                "--port": self.port, "--ray-client-server-port": free_port(), "--dashboard-port": self.dashboard_port,
            })
        command = [
            RAY, "start", "--block", "--disable-usage-stats", f"--num-cpus={num_cpus}",
            f"--resources={json.dumps(resources or {})}", "--node-ip-address=127.0.0.1",
            f"--temp-dir={self.temp_dir}",
            *(["--head", "--include-dashboard=true", "--dashboard-host=127.0.0.1"]
              if head else [f"--address={self.address}"]),
            *(f"{flag}={port}" for flag, port in ports.items()),
        ]
        log = self.temp_dir / f"node{len(self.nodes)}.log"
        with open(log, "w") as out:
            process = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT, env=self.env, start_new_session=True)
        node = Node(process, log)
        self.nodes.append(node)
        deadline = time.monotonic() + NODE_START_S
        while "Ray runtime started" not in log.read_text():
            if process.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"ray start failed (exit {process.poll()}):\n{log.read_text()[-3000:]}")
            time.sleep(0.5)
        return node

    def kill(self, node: Node) -> None:
        """The node dies at once, as a machine would: SIGKILL to its ``ray start``, whose Ray
        processes die with it (Ray makes them share its fate)."""
        node.process.kill()
        node.process.wait()

    def actors(self, class_name: str) -> list[dict]:
        """The cluster's actors of ``class_name``, dead ones too, from Ray's state API."""
        done = subprocess.run(
            [RAY, "list", "actors", f"--address=http://127.0.0.1:{self.dashboard_port}", "--filter",
             f"class_name={class_name}", "--detail", "--format=json", "--limit=1000"],
            capture_output=True, text=True, env=self.env, timeout=120,
        )
        if done.returncode:
            raise RuntimeError(f"ray list actors failed: {done.stderr[-2000:]}")
        return json.loads(done.stdout)

    def node_ids(self) -> list[str]:
        done = subprocess.run(
            [RAY, "list", "nodes", f"--address=http://127.0.0.1:{self.dashboard_port}", "--format=json"],
            capture_output=True, text=True, env=self.env, timeout=120,
        )
        if done.returncode:
            raise RuntimeError(f"ray list nodes failed: {done.stderr[-2000:]}")
        return sorted(node["node_id"] for node in json.loads(done.stdout))

    def stop(self) -> None:
        """Kill every node this cluster started (workers first), then whatever is left of them.
        (SIGTERM would stop a node gracefully, as the docs say, but drains it first: some 40 s
        on a loaded machine, which a test has no use for.)"""
        for node in reversed(self.nodes):
            self.kill(node)
        for pid in self.leftover_pids():
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        shutil.rmtree(self.temp_dir, ignore_errors=True)

    def leftover_pids(self) -> list[int]:
        """Processes still running with this cluster's temporary directory in their command line
        (the head's processes name it; a worker node's name the head's session under it)."""
        found = []
        for entry in Path("/proc").iterdir():
            if entry.name.isdigit() and int(entry.name) != os.getpid():
                try:
                    command = (entry / "cmdline").read_bytes().decode(errors="replace")
                except OSError:
                    continue
                if str(self.temp_dir) in command:
                    found.append(int(entry.name))
        return found

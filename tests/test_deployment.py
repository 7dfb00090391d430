"""The deployment files (docker/): what can be checked without Docker or Kubernetes.

Every container start goes through league.start_or_resume (its logic is tested in
tests/commands/test_start_or_resume.py), the RayJob's volume claim is defined, the image
installs its dependencies in a layer before the source, and the build context is an allowlist.
"""

from __future__ import annotations

import re
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parent.parent
DOCKER = ROOT / "docker"
ENTRYPOINT = "python -m league.start_or_resume"


def config_of(command: str) -> str:
    """The config a command names (a compose variable's default: ``${CONFIG:-cluster}``)."""
    return re.search(r"--config\s+(?:\$\{CONFIG:-)?([\w.-]+)", command).group(1)


def test_the_compose_trainer_starts_or_resumes_the_run_on_its_volume():
    compose = yaml.safe_load((DOCKER / "docker-compose.yml").read_text())
    trainer = compose["services"]["trainer"]
    assert f"exec {ENTRYPOINT} --config" in trainer["command"]
    assert trainer["restart"] == "on-failure"
    volume, mount = trainer["volumes"][0].split(":")
    assert volume in compose["volumes"] and mount == "/home/league/runs"  # the image's WORKDIR/runs
    assert (ROOT / "configs" / f"{config_of(trainer['command'])}.yaml").exists()


def test_the_rayjob_starts_or_resumes_and_its_volume_claim_is_defined():
    documents = list(yaml.safe_load_all((DOCKER / "kuberay-rayjob.yaml").read_text()))
    [job] = [d for d in documents if d["kind"] == "RayJob"]
    assert job["spec"]["entrypoint"].startswith(f"{ENTRYPOINT} --config")
    assert (ROOT / "configs" / f"{config_of(job['spec']['entrypoint'])}.yaml").exists()
    claims = {d["metadata"]["name"] for d in documents if d["kind"] == "PersistentVolumeClaim"}
    pods = [job["spec"]["rayClusterSpec"]["headGroupSpec"], *job["spec"]["rayClusterSpec"]["workerGroupSpecs"]]
    used = {
        volume["persistentVolumeClaim"]["claimName"]
        for pod in pods for volume in pod["template"]["spec"].get("volumes", []) if "persistentVolumeClaim" in volume
    }
    assert used and used <= claims


def test_the_image_installs_its_dependencies_before_the_source():
    lines = [line for line in (DOCKER / "Dockerfile").read_text().splitlines() if not line.startswith("#")]
    stages = [i for i, line in enumerate(lines) if line.startswith("FROM ")]
    # The base is an ARG (a local stand-in can be passed) whose default is the official image's full tag.
    assert lines[stages[0]] == "FROM ${BASE} AS deps" and lines[stages[0] - 1].startswith("ARG BASE="), lines[: stages[0] + 1]
    default = lines[stages[0] - 1].removeprefix("ARG BASE=")
    assert re.fullmatch(r"python:\d+\.\d+\.\d+-slim-\w+(@sha256:[0-9a-f]{64})?", default), default  # a full tag
    deps, final = lines[stages[0] : stages[1]], lines[stages[-1] :]
    assert any("-c /tmp/deps/constraints.txt" in line for line in deps)
    assert [line for line in deps if line.startswith("COPY ")] == ["COPY pyproject.toml constraints.txt /tmp/deps/"]
    # On the dependencies' layers, the final stage adds the package only as the wheel built in its own stage.
    assert final[0] == "FROM deps" and not any("--mount" in line for line in final)
    assert [line for line in final if line.startswith("COPY ")] == ["COPY --from=wheel /tmp/wheel/ /tmp/wheel/"]


def test_the_build_context_is_only_what_the_package_is_built_from():
    patterns = [line for line in (ROOT / ".dockerignore").read_text().splitlines() if line and not line.startswith("#")]
    assert patterns[0] == "*"
    allowed = {p[1:].rstrip("/") for p in patterns if p.startswith("!")}
    assert allowed == {"pyproject.toml", "README.md", "LICENSE", "constraints.txt", "envs", "league", "configs"}

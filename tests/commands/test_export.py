"""Exported policies act like the league's modules, without Ray."""

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import torch

from envs.agents import AGENTS
from envs.config import GameConfig
from envs.match import play, scripted_players
from envs.scenarios import evaluation_scenarios
from league.export import main as export_main
from league.evaluation.engine import LearnedAgent, load_module

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def run_dir(tiny_run):
    return tiny_run


def observations(module, agent: str, n: int = 1000) -> np.ndarray:
    """Observations of ``agent`` from real episodes: the module's side against scripted players."""
    players = scripted_players("lead_intercept", "avoid_attacker", "pure_pursuit")
    for name in ("attacker",) if agent == "attacker" else ("targeter", "defender"):
        players[name] = LearnedAgent(module, name)
    recorded = []

    class Recorder:
        def __init__(self, inner):
            self.inner = inner

        def act(self, game):
            recorded.append(game.observations()[AGENTS.index(agent)][game.active])
            return self.inner.act(game)

    players[agent] = Recorder(players[agent])
    play(GameConfig(), players, evaluation_scenarios("default", 200))
    obs = np.concatenate(recorded)
    assert len(obs) >= n
    return obs[:n]


def rllib_actions(module, obs: np.ndarray) -> np.ndarray:
    with torch.no_grad():
        padded = torch.from_numpy(np.concatenate((obs, np.zeros((len(obs), 22), np.float32)), axis=1))
        return module.deterministic_action(padded).numpy()


WITHOUT_RAY = textwrap.dedent(
    """
    import sys, json
    import numpy as np
    fmt, model, obs_file, out_file = sys.argv[1:]
    obs = np.load(obs_file)
    if fmt == "export":
        import torch
        extra = {"metadata.json": ""}
        policy = torch.export.load(model, extra_files=extra).module()
        actions = policy(torch.from_numpy(obs)).detach().numpy()
        meta = json.loads(extra["metadata.json"])
    elif fmt == "torchscript":
        import torch
        extra = {"metadata.json": ""}
        policy = torch.jit.load(model, _extra_files=extra)
        actions = policy(torch.from_numpy(obs)).detach().numpy()
        meta = json.loads(extra["metadata.json"])
    else:
        import onnx, onnxruntime
        meta = json.loads({p.key: p.value for p in onnx.load(model).metadata_props}["metadata.json"])
        session = onnxruntime.InferenceSession(model)
        actions = session.run(None, {"observation": obs})[0]
    assert "ray" not in sys.modules, "ray was imported"
    np.save(out_file, actions)
    print(json.dumps(meta))
    """
)


@pytest.mark.parametrize("fmt, suffix", [("export", "pt2"), ("torchscript", "pt"), ("onnx", "onnx")])
@pytest.mark.parametrize("player, agent", [("latest-attacker", "attacker"), ("latest-team", "defender")])
def test_exported_policy_matches_the_rllib_module_without_ray(run_dir, tmp_path, fmt, suffix, player, agent):
    out = tmp_path / f"policy.{suffix}"
    assert export_main(["--run-dir", str(run_dir), "--player", player, "--format", fmt, "--out", str(out)]) == 0
    side = "attacker" if agent == "attacker" else "team"
    module = load_module(run_dir / "players" / ("attacker-m2-v1" if side == "attacker" else "team-v1"))
    obs = observations(module, agent)
    np.save(tmp_path / "obs.npy", obs)
    proc = subprocess.run(
        [sys.executable, "-c", WITHOUT_RAY, fmt, str(out), str(tmp_path / "obs.npy"), str(tmp_path / "actions.npy")],
        capture_output=True, text=True, cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    meta = json.loads(proc.stdout.strip().splitlines()[-1])
    assert meta["player"]["side"] == side and meta["observation"]["size"] == obs.shape[1]
    assert meta["action"]["mode"] == "relative" and meta["game"]["v_attacker"] == 0.18
    exported = np.load(tmp_path / "actions.npy")
    expected = rllib_actions(module, obs)
    # float32 actions of size ~1: another kernel or summation order changes only the last of ~7 digits.
    assert np.abs(exported - expected).max() < 1e-5
    assert np.abs(expected).max() > 1e-3  # a policy that does something, not all zeros


class ExportedAgent:
    def __init__(self, policy, agent):
        self.policy, self.index = policy, AGENTS.index(agent)

    def act(self, game):
        with torch.no_grad():
            return self.policy(torch.from_numpy(game.observations()[self.index])).numpy().astype(np.float64)


def test_exported_policy_plays_the_same_episodes_as_in_the_league(run_dir, tmp_path):
    out = tmp_path / "attacker.pt2"
    assert export_main(["--run-dir", str(run_dir), "--player", "latest-attacker", "--format", "export", "--out", str(out)]) == 0
    module = load_module(run_dir / "players" / "attacker-m2-v1")
    games = evaluation_scenarios("default", 300)
    inside = scripted_players("lead_intercept", "avoid_attacker", "pure_pursuit")
    inside["attacker"] = LearnedAgent(module, "attacker")
    exported = dict(inside)
    exported["attacker"] = ExportedAgent(torch.export.load(str(out)).module(), "attacker")
    a, b = play(GameConfig(), inside, games), play(GameConfig(), exported, games)
    # Exact outcomes: both run the module's own operations on the same 300-row batches in the
    # same order (the exported graph is traced from them), so they round alike on any CPU.
    np.testing.assert_array_equal(a.outcome, b.outcome)
    np.testing.assert_array_equal(a.steps, b.steps)
    np.testing.assert_allclose(a.returns, b.returns, atol=1e-4)


def test_missing_player_and_corrupt_checkpoint_are_clear_errors(run_dir, tmp_path, capsys):
    out = tmp_path / "x.pt"
    assert export_main(["--run-dir", str(run_dir), "--player", "attacker-m2-v9", "--out", str(out)]) == 2
    assert "no player 'attacker-m2-v9'" in capsys.readouterr().err
    assert export_main(["--run-dir", str(run_dir), "--player", "scripted-lead_intercept", "--out", str(out)]) == 2
    assert "only snapshots" in capsys.readouterr().err
    broken = tmp_path / "broken"
    subprocess.run(["cp", "-r", str(run_dir), str(broken)], check=True)
    (broken / "players" / "team-v1" / "module_state.pkl").write_bytes(b"not a pickle")
    assert export_main(["--run-dir", str(broken), "--player", "team-v1", "--out", str(out)]) == 2
    assert "cannot be read" in capsys.readouterr().err
    assert not out.exists()


def test_readme_example_runs(run_dir, tmp_path):
    """The export example of docs/evaluation.md, as written, with an attacker exported from a run."""
    out = tmp_path / "attacker.pt2"
    assert export_main(["--run-dir", str(run_dir), "--player", "latest-attacker", "--format", "export", "--out", str(out)]) == 0
    readme = (REPO / "docs" / "evaluation.md").read_text()
    block = readme.split("<!-- export-example -->", 1)[1].split("```python", 1)[1].split("```", 1)[0]
    proc = subprocess.run([sys.executable, "-c", block], capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]


@pytest.mark.parametrize("fmt, suffix", [("export", "pt2"), ("torchscript", "pt")])
def test_an_observation_of_another_width_is_refused(run_dir, tmp_path, fmt, suffix):
    out = tmp_path / f"attacker.{suffix}"
    assert export_main(["--run-dir", str(run_dir), "--player", "latest-attacker", "--format", fmt, "--out", str(out)]) == 0
    policy = torch.export.load(str(out)).module() if fmt == "export" else torch.jit.load(str(out))
    size = load_module(run_dir / "players" / "attacker-m2-v1").actor_inputs
    assert policy(torch.zeros(3, size)).shape == (3, 2)
    for wrong in (torch.zeros(1, 23), torch.zeros(1, 100), torch.zeros(size)):  # the team's width, any other, no batch
        with pytest.raises(Exception):
            policy(wrong)


def test_the_torchscript_archive_is_named_after_its_file(run_dir, tmp_path):
    import zipfile

    out = tmp_path / "attacker.pt"
    assert export_main(["--run-dir", str(run_dir), "--player", "latest-attacker", "--format", "torchscript", "--out", str(out)]) == 0
    names = zipfile.ZipFile(out).namelist()
    assert names and all(name.startswith("attacker/") for name in names), names[:3]
    assert [p.name for p in tmp_path.iterdir()] == ["attacker.pt"]  # nothing left beside it


def test_the_torchscript_width_error_gives_the_expected_and_the_given_shape(run_dir, tmp_path):
    torch.set_num_threads(1)
    out = tmp_path / "attacker.pt"
    assert export_main(["--run-dir", str(run_dir), "--player", "latest-attacker", "--format", "torchscript", "--out", str(out)]) == 0
    policy = torch.jit.load(str(out))
    size = load_module(run_dir / "players" / "attacker-m2-v1").actor_inputs
    for wrong, shape in ((torch.zeros(1, 23), "[1, 23]"), (torch.zeros(size), f"[{size}]")):
        with pytest.raises(Exception, match=rf"batch \(B, {size}\).*got shape \[") as raised:
            policy(wrong)
        assert f"got shape {shape}" in str(raised.value)

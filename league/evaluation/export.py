"""A league player's policy as a standalone torch module, as the evaluation engine plays it (the
Gaussian's mean), written as torch.export, TorchScript or ONNX (``python -m league.export``).

The metadata travels inside the file (``.pt2`` and TorchScript extra file ``metadata.json``;
ONNX ``metadata_props``): observation and action layout, game parameters, player, versions.
"""

from __future__ import annotations

import json
import shutil
import warnings
from pathlib import Path
from typing import Any

import torch
from torch import nn

import league
from envs.observations import split_policy_input
from envs.single import action_space, observation_space
from league.core.players import POOL_KINDS, Player
from league.state.run_dir import RunDirError, open_run
from league.state.store import LeagueStore

METADATA_FILE = "metadata.json"
FORMATS = ("export", "torchscript", "onnx")


class ExportError(ValueError):
    pass


class ExportedPolicy(nn.Module):
    """The actor of a league ``ActorCriticModule``: own observation -> mean action."""

    def __init__(self, actor: nn.Module, observation_size: int):
        super().__init__()
        self.actor = actor
        self.observation_size = observation_size

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        # A batch of another width (another agent's observation, a wrong layout) is refused, not
        # sliced: in TorchScript here; `torch.export` and ONNX check the traced shape themselves.
        if observation.dim() != 2 or observation.size(1) != self.observation_size:
            raise ValueError(
                "observation must be a float32 batch (B, {}), this agent's observation size (metadata.json); "
                "got shape {}".format(self.observation_size, [int(n) for n in observation.shape])
            )
        return self.actor(split_policy_input(observation, self.observation_size)[0])


def resolve_player(store: LeagueStore, spec: str) -> Player:
    """A player by id, by name, or ``latest-attacker`` / ``latest-team`` (newest snapshot)."""
    players = store.players()
    if spec in ("latest-attacker", "latest-team"):
        side = spec.split("-", 1)[1]
        snapshots = [p for p in players if p.side == side and p.kind == "snapshot"]
        if not snapshots:
            raise ExportError(f"the league has no {side} snapshot yet")
        return snapshots[-1]
    chosen = [p for p in players if str(p.id) == spec or p.name == spec]
    if not chosen:
        known = ", ".join(p.name for p in players if p.kind in POOL_KINDS)
        raise ExportError(f"no player {spec!r} in the league (snapshots: {known})")
    if chosen[0].kind not in POOL_KINDS:
        raise ExportError(f"player {spec!r} is {chosen[0].kind}: only snapshots (and exploiter snapshots) have a saved policy to export")
    return chosen[0]


def load_policy(run_dir: Path, player: Player) -> tuple[nn.Module, Any]:
    """The player's RLModule, with a clear error for a missing or unreadable checkpoint."""
    from league.evaluation.engine import MissingModuleError, saved_module

    path = run_dir / (player.checkpoint or "")
    try:
        return saved_module(player, run_dir)
    except MissingModuleError as err:
        raise ExportError(str(err)) from err
    except Exception as err:  # a truncated or foreign file: unpickling fails in many ways
        raise ExportError(f"checkpoint of {player.name} at {path} cannot be read: {type(err).__name__}: {err}") from err


def metadata(run: Any, player: Player, module: Any) -> dict[str, Any]:
    import ray

    agent = "attacker" if player.side == "attacker" else "targeter"
    obs_space, act_space = observation_space(run.game, agent), action_space(run.game)
    return {
        "player": {"id": player.id, "name": player.name, "side": player.side, "reward_method": player.reward_method,
                   "version": player.version, "env_steps": player.env_steps},
        "agents": ["attacker"] if player.side == "attacker" else ["targeter", "defender"],
        "observation": {
            "mode": run.game.observation,
            "size": int(obs_space.shape[0]),
            "layout": "envs.observations (rich: agent-centred, lengths / position_scale; T and D end with a role "
            "one-hot (targeter, defender))",
        },
        "action": {
            "mode": run.game.action_mode,
            "low": act_space.low.tolist(),
            "high": act_space.high.tolist(),
            "meaning": "relative: (yaw change / max_yaw_change, pitch change / max_pitch_change)"
            if run.game.action_mode == "relative" else "absolute: desired (yaw, pitch) in radians",
            "output": "Gaussian mean; the env clips it into [low, high]",
        },
        "game": run.game.model_dump(),
        "versions": {"torch": torch.__version__, "ray": ray.__version__, "package": f"target-defense-league {league.__version__}"},
        "hidden": list(module.settings.hidden),
    }


def build(run_dir: Path, spec: str) -> tuple[ExportedPolicy, dict[str, Any]]:
    try:
        run, store = open_run(run_dir)
    except RunDirError as err:
        raise ExportError(str(err)) from err
    try:
        player = resolve_player(store, spec)
    finally:
        store.close()
    module = load_policy(run_dir, player)
    policy = ExportedPolicy(module.pi, module.actor_inputs).eval()
    return policy, metadata(run, player, module)


def export(policy: ExportedPolicy, info: dict[str, Any], fmt: str, out: Path) -> None:
    example = torch.zeros(1, info["observation"]["size"])
    out.parent.mkdir(parents=True, exist_ok=True)
    # Written under its own name in a hidden directory beside it (the archive's folder inside
    # the file is named after the file), then moved: never a half-written file under that name.
    scratch = out.parent / f".{out.name}.partial"
    shutil.rmtree(scratch, ignore_errors=True)
    scratch.mkdir()
    try:
        partial = scratch / out.name
        _write(policy, info, fmt, example, partial)
        partial.replace(out)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _write(policy: ExportedPolicy, info: dict[str, Any], fmt: str, example: torch.Tensor, partial: Path) -> None:
    if fmt == "export":
        # A batch of 2 to trace: torch.export specialises a dimension of size 1 to a constant.
        program = torch.export.export(policy, (example.expand(2, -1),),
                                      dynamic_shapes={"observation": {0: torch.export.Dim("batch")}})
        torch.export.save(program, str(partial), extra_files={METADATA_FILE: json.dumps(info)})
    elif fmt == "torchscript":
        with warnings.catch_warnings():  # torch 2.13 marks torch.jit deprecated; the format is kept on purpose
            warnings.simplefilter("ignore", DeprecationWarning)
            torch.jit.save(torch.jit.script(policy), str(partial), _extra_files={METADATA_FILE: json.dumps(info)})
    else:
        import onnx

        with warnings.catch_warnings():  # the TorchScript-based exporter is the one that needs no onnxscript
            warnings.simplefilter("ignore", DeprecationWarning)
            torch.onnx.export(
                policy, (example,), str(partial), input_names=["observation"], output_names=["action"],
                dynamic_axes={"observation": {0: "batch"}, "action": {0: "batch"}}, dynamo=False,
            )
        model = onnx.load(str(partial))
        onnx.helper.set_model_props(model, {METADATA_FILE: json.dumps(info)})
        onnx.save(model, str(partial))

"""A league player's policy as a standalone torch module, as the evaluation engine plays it (the
Gaussian's mean), written as torch.export, TorchScript or ONNX (``python -m league.export``).

A mixture player (``nash-attacker``, ``nash-team``, ``@ITERATION``; ``league.core.mixture``) is
one module holding every member's policy, ``ExportedMixture``: it draws each game's member from
``(seed, game)`` by the same integer arithmetic as evaluation, so a seed gives the same members
here as in ``league.evaluate --mixture-seed``. Scripted members act on the game's exact state,
not on an observation: a mixture with one is refused, naming it.

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
from league.core.mixture import (
    MIX_INCREMENT, MIX_KEYS, MIX_MULTIPLIER, MODULUS, Mixture, MixtureError, boundaries, is_mixture_name,
)
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


class ExportedMixture(nn.Module):
    """A mixture player: every member's policy, one drawn per game.

    ``forward(observation, seed, game)``: ``observation`` a float32 batch ``(B, size)`` as for one
    player; ``seed`` and ``game`` int64 ``(B,)``, each row's seed (0 to 2**31 - 2) and game number
    (from 0). Returns ``(action (B, 2), member (B,))``: the action of the member drawn for the row's
    ``(seed, game)`` (``member``: its index in the metadata's ``mixture.members``). Give every row of
    one game (the team's targeter and defender, every step) the same seed and game number: the game
    is played by one member. The draw is ``league.core.mixture``'s, so seed ``s`` and game ``k`` draw
    the member that plays fixed game ``k`` in ``league.evaluate --mixture-seed s``.
    """

    def __init__(self, members: list[ExportedPolicy], bounds: torch.Tensor, stream: int):
        super().__init__()
        self.members = nn.ModuleList(members)
        self.register_buffer("boundaries", bounds)
        self.stream = stream
        # league.core.mixture's constants as attributes: TorchScript reads no global variables
        self.modulus, self.keys, self.increment, self.multiplier = MODULUS, list(MIX_KEYS), MIX_INCREMENT, MIX_MULTIPLIER

    def mix(self, x: torch.Tensor) -> torch.Tensor:
        """``league.core.mixture.mix`` on int64 tensors (TorchScript compiles it, so it cannot be NumPy's)."""
        x = torch.remainder(x, self.modulus)
        for k in self.keys:
            x = torch.remainder(x * (x + k) + self.increment, self.modulus)
            x = torch.remainder(x * self.multiplier, self.modulus)
        return x

    def member(self, seed: torch.Tensor, game: torch.Tensor) -> torch.Tensor:
        """Each row's member index, from its ``(seed, game)``."""
        keys = self.mix(self.mix(self.mix(seed) + self.stream) + game)
        return (keys.unsqueeze(1) >= self.boundaries.unsqueeze(0)).to(torch.int64).sum(1)

    def forward(self, observation: torch.Tensor, seed: torch.Tensor, game: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        member = self.member(seed, game)
        actions = []
        for policy in self.members:  # every member acts on every row; the drawn one's action is kept
            actions.append(policy(observation))
        stacked = torch.stack(actions, dim=1)  # (B, members, 2)
        chosen = torch.gather(stacked, 1, member.view(-1, 1, 1).expand(-1, 1, stacked.size(2))).squeeze(1)
        return chosen, member


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
            "one-hot (targeter, defender); with game.attacker_memory A's ends with T's largest turn away from home)",
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


def build(run_dir: Path, spec: str) -> tuple[nn.Module, dict[str, Any]]:
    """The player ``spec`` (``resolve_player``'s, or a mixture's name) as a module, and its metadata."""
    from league.analysis.mixtures import store_mixture

    try:
        run, store = open_run(run_dir)
    except RunDirError as err:
        raise ExportError(str(err)) from err
    try:
        if is_mixture_name(spec):
            try:
                return build_mixture(run, run_dir, store_mixture(store, spec))
            except MixtureError as err:
                raise ExportError(str(err)) from None
        player = resolve_player(store, spec)
    finally:
        store.close()
    module = load_policy(run_dir, player)
    policy = ExportedPolicy(module.pi, module.actor_inputs).eval()
    return policy, metadata(run, player, module)


def build_mixture(run: Any, run_dir: Path, mixture: Mixture) -> tuple[ExportedMixture, dict[str, Any]]:
    """``mixture`` as one ``ExportedMixture``; one with scripted members is refused, naming them."""
    scripted = mixture.scripted_members()
    if scripted:
        raise ExportError(
            f"{mixture.name} has scripted members ({', '.join(p.name for p in scripted)}): they act on the game's exact "
            "state, not on an observation, so they cannot be exported; export a trained player, or a mixture without them"
        )
    modules = [load_policy(run_dir, player) for player in mixture.members]
    policies = [ExportedPolicy(m.pi, m.actor_inputs) for m in modules]
    exported = ExportedMixture(policies, torch.from_numpy(boundaries(mixture.weights)), mixture.stream).eval()
    info = metadata(run, mixture.members[0], modules[0])
    info["player"] = {"name": mixture.name, "side": mixture.side, "mixture": True}
    info["mixture"] = {
        **mixture.as_json(),
        "members": [{**row, "reward_method": p.reward_method, "version": p.version, "env_steps": p.env_steps,
                     "hidden": list(m.settings.hidden)}
                    for row, p, m in zip(mixture.as_json()["members"], mixture.members, modules)],
        "interface": "forward(observation float32 (B, size), seed int64 (B,), game int64 (B,)) -> "
                     "(action float32 (B, 2), member int64 (B,)); one member per (seed, game), league.core.mixture's draw",
    }
    info["hidden"] = [list(m.settings.hidden) for m in modules]
    return exported, info


def example_inputs(policy: nn.Module, info: dict[str, Any], batch: int) -> tuple[torch.Tensor, ...]:
    """Inputs of ``batch`` rows to trace ``policy`` with: an observation batch, and a mixture's seeds and games."""
    observation = torch.zeros(batch, info["observation"]["size"])
    if isinstance(policy, ExportedMixture):
        return observation, torch.zeros(batch, dtype=torch.int64), torch.arange(batch, dtype=torch.int64)
    return (observation,)


def export(policy: nn.Module, info: dict[str, Any], fmt: str, out: Path) -> None:
    out.parent.mkdir(parents=True, exist_ok=True)
    # Written under its own name in a hidden directory beside it (the archive's folder inside
    # the file is named after the file), then moved: never a half-written file under that name.
    scratch = out.parent / f".{out.name}.partial"
    shutil.rmtree(scratch, ignore_errors=True)
    scratch.mkdir()
    try:
        partial = scratch / out.name
        _write(policy, info, fmt, partial)
        partial.replace(out)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _write(policy: nn.Module, info: dict[str, Any], fmt: str, partial: Path) -> None:
    mixture = isinstance(policy, ExportedMixture)
    inputs, outputs = (["observation", "seed", "game"], ["action", "member"]) if mixture else (["observation"], ["action"])
    if fmt == "export":
        # A batch of 2 to trace: torch.export specialises a dimension of size 1 to a constant.
        batch = torch.export.Dim("batch")
        program = torch.export.export(policy, example_inputs(policy, info, 2),
                                      dynamic_shapes={name: {0: batch} for name in inputs})
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
                policy, example_inputs(policy, info, 1), str(partial), input_names=inputs, output_names=outputs,
                dynamic_axes={name: {0: "batch"} for name in inputs + outputs}, dynamo=False,
            )
        model = onnx.load(str(partial))
        onnx.helper.set_model_props(model, {METADATA_FILE: json.dumps(info)})
        onnx.save(model, str(partial))

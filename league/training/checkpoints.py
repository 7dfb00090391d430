"""The files a training run writes besides its database: frozen players' modules and checkpoints.

A snapshot's module goes to ``players/NAME`` (``freeze``); a checkpoint directory holds the
algorithm, the env runners' games in flight and the batch sampled ahead (``write_checkpoint``), written whole or not
at all (``league.state.run_dir.write_checkpoint``); ``restore`` reads one back.
"""

from __future__ import annotations

import pickle
from dataclasses import replace
from pathlib import Path
from typing import Any

from league.config import RunConfig
from league.core.players import NewPlayer, Player
from league.rllib import bridge
from league.state.run_dir import fresh_directory, write_checkpoint

GAMES_FILE = "games_in_flight.pkl"  # in a checkpoint directory: the env runners' games in flight
AHEAD_FILE = "sampled_ahead.pkl"  # in a checkpoint directory: the batch sampled ahead (`resources.sample_ahead`)


def save_player(algo: Any, run_dir: Path, module_id: str, name: str) -> str:
    """Save ``module_id`` as the player ``name`` (``players/NAME``, anything there before replaced); its path in the run."""
    path = fresh_directory(run_dir / "players" / name)  # (one left over by a run killed before it committed is replaced)
    bridge.save_module(algo, module_id, path)
    return str(path.relative_to(run_dir))


def freeze(algo: Any, run: RunConfig, run_dir: Path, trainee: Player, snapshot: NewPlayer) -> NewPlayer:
    """Add ``snapshot``, a frozen copy of ``trainee``'s module, to the algorithm and save it; with its checkpoint."""
    bridge.add_snapshot(algo, run, snapshot, trainee.name)
    return replace(snapshot, checkpoint=save_player(algo, run_dir, snapshot.name, snapshot.name))


def checkpoint(algo: Any, run_dir: Path, iteration: int) -> Path:
    """The algorithm and the env runners' games in flight, in ``iteration``'s checkpoint directory."""

    def save(directory: Path) -> None:
        algo.save_to_path(str(directory))
        (directory / GAMES_FILE).write_bytes(pickle.dumps(bridge.games_in_flight(algo)))
        ahead = bridge.batch_sampled_ahead(algo)
        if ahead is not None:
            (directory / AHEAD_FILE).write_bytes(pickle.dumps(ahead))

    return write_checkpoint(run_dir, iteration, save)


def restore(directory: Path) -> Any:
    """The algorithm of a checkpoint directory, with its games in flight."""
    algo = bridge.restore_algorithm(directory)
    games = directory / GAMES_FILE
    if games.exists():  # (a checkpoint written before games in flight were kept has none: they start anew)
        bridge.restore_games(algo, pickle.loads(games.read_bytes()))
    ahead = directory / AHEAD_FILE
    if ahead.exists():
        bridge.restore_batch_sampled_ahead(algo, pickle.loads(ahead.read_bytes()))
    return algo

"""Recorded games shown as 3D trajectories: a won and a lost game of each side for the report,
and one fixed evaluation game for ``league.replay``.

The games are the fixed evaluation games, played with deterministic actions by
``envs.match.play`` with the players' controllers (``league.evaluation.engine.agents_of``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from envs.agents import Outcome
from envs.match import play
from envs.scenarios import evaluation_scenarios
from league.analysis.nash import meta_game_players
from league.config import RunConfig
from league.core.payoff import wins_of, winner
from league.core.players import Player
from league.evaluation.engine import agents_of

TRAJECTORY_GAMES = 200


@dataclass(frozen=True)
class Episode:
    """One recorded game shown as a trajectory: ``side`` won or lost it."""

    side: str
    label: str  # "won" or "lost"
    pairing: str  # "ATTACKER vs TEAM (game G)"
    path: np.ndarray  # (steps + 1, 3 agents, 3) positions
    outcome: Outcome


@dataclass
class Trajectories:
    """The report's recorded games, and why a won or lost game of a side is not among them."""

    episodes: list[Episode]
    missing: list[str]


def record_episodes(run: RunConfig, run_dir: Path, attacker: Player, team: Player, side: str) -> tuple[list[Episode], list[str]]:
    """The first won and the first lost game of ``side`` in ``attacker`` vs ``team``; or why there is none."""
    players = {**agents_of(attacker, run_dir), **agents_of(team, run_dir)}
    result = play(run.game, players, evaluation_scenarios(run.game.scenario, TRAJECTORY_GAMES), record=True)
    paths = np.stack(result.trajectory)  # (steps + 1, games, 3, 3)
    side_won = wins_of(side, result.attacker_wins.astype(int), 1) == 1
    learned = attacker if side == "attacker" else team
    episodes, missing = [], []
    for label, mask in (("won", side_won), ("lost", ~side_won)):
        games = np.flatnonzero(mask)
        if not len(games):
            missing.append(f"{learned.name} ({side}) {'never won' if label == 'won' else 'never lost'} "
                           f"in {TRAJECTORY_GAMES} fixed games of {attacker.name} vs {team.name}.")
            continue
        g = int(games[0])
        pairing = f"{attacker.name} vs {team.name} (game {g})"
        episodes.append(Episode(side, label, pairing, paths[: int(result.steps[g]) + 1, g], Outcome(int(result.outcome[g]))))
    return episodes, missing


def report_trajectories(run: RunConfig, run_dir: Path, players: list[Player]) -> Trajectories:
    """A won and a lost game of each side's newest snapshot against a scripted opponent (the paper's team when there is one)."""
    attackers, teams = meta_game_players(players)  # snapshots and scripted players
    scripted_teams = [t for t in teams if t.kind == "scripted"]
    paper_team = next((t for t in scripted_teams if t.is_paper_team),
                      scripted_teams[0] if scripted_teams else None)
    scripted_attacker = next((a for a in attackers if a.kind == "scripted"), None)
    newest_attacker = next((a for a in reversed(attackers) if a.kind == "snapshot"), None)
    newest_team = next((t for t in reversed(teams) if t.kind == "snapshot"), None)
    episodes, missing = [], []
    for side, attacker, team in (("attacker", newest_attacker, paper_team), ("team", scripted_attacker, newest_team)):
        if attacker is None or team is None:
            missing.append(f"No {side} trajectories: the league has no {side} snapshot or no scripted opponent for it.")
            continue
        shown, why = record_episodes(run, run_dir, attacker, team, side)
        episodes += shown
        missing += why
    return Trajectories(episodes, missing)


def replay_game(run: RunConfig, run_dir: Path, attacker: Player, team: Player, game: int) -> tuple[Episode, int]:
    """Fixed evaluation game ``game`` of ``attacker`` vs ``team``, as won by its winner, and its steps."""
    start = evaluation_scenarios(run.game.scenario, game + 1)[game:]
    controllers = {**agents_of(attacker, run_dir), **agents_of(team, run_dir)}
    result = play(run.game, controllers, start, record=True)
    steps, outcome = int(result.steps[0]), Outcome(int(result.outcome[0]))
    path = np.stack([frame[0] for frame in result.trajectory][: steps + 1])  # (steps + 1, 3 agents, 3)
    pairing = f"{attacker.name} vs {team.name} (game {game})"
    return Episode(winner(outcome.label), "won", pairing, path, outcome), steps

"""Play whole games on the batched core: the scripted table, recorded trajectories for rendering.

A *controller* picks one agent's actions: anything with ``act(game) -> (N, 2)``, such as
``envs.scripted.ScriptedPlayer`` or a learned policy wrapped by the caller. The league's
evaluation plays its games with the rollout (``league.rollout.games``), which gives the same
outcomes on the same games (``tests/evaluation/test_engine.py``).

``python -m envs.match --episodes 1000`` (``envs-match`` once installed) prints the
scripted-vs-scripted win rates on the ``dev`` games (``--games test``: the held-out ones);
``--by-class`` gives each matchup's attacker win rate with its 95% Wilson interval overall and
on the games of each start class (``envs.start_classes``: T-race, A-certain, contested) and
the class counts of the games; ``--version`` the installed package's version (read from its metadata:
``envs`` knows nothing of ``league``, whose commands print the same number).
"""

from __future__ import annotations

import argparse
import importlib.metadata
import math
import sys
from dataclasses import dataclass, field
from typing import Iterator, Protocol

import numpy as np

from envs.agents import AGENTS, ATTACKER_WIN_VALUES, Outcome
from envs.config import GameConfig
from envs.core import BatchedGame
from envs.scenarios import GAME_SETS, SCENARIO_SETS, evaluation_scenarios
from envs.scripted import PLAYERS, ScriptedPlayer
from envs.start_classes import StartClass, class_counts, classify

DISTRIBUTION = "target-defense-league"  # pyproject.toml's project name
Z_95 = 1.959963984540054


def wilson_interval(wins: int, games: int, z: float = Z_95) -> tuple[float, float]:
    """95% Wilson score interval of a win rate."""
    if games == 0:
        return (0.0, 1.0)
    p = wins / games
    denom = 1 + z * z / games
    centre = (p + z * z / (2 * games)) / denom
    half = z * math.sqrt(p * (1 - p) / games + z * z / (4 * games * games)) / denom
    return (max(0.0, centre - half), min(1.0, centre + half))


class Controller(Protocol):
    """Picks the actions of one agent in every game of a batch."""

    def act(self, game: BatchedGame) -> np.ndarray: ...


@dataclass
class GameResults:
    """Per-game results of a batch of games played to the end."""

    outcome: np.ndarray  # (N,) Outcome values
    steps: np.ndarray  # (N,) steps played
    returns: np.ndarray  # (N, 3) summed rewards
    trajectory: list[np.ndarray] = field(default_factory=list)  # positions (N, 3, 3) per step, if recorded
    attacker_returns: np.ndarray | None = None  # (N, 3) A's summed rewards under methods 1, 2, 3

    @property
    def attacker_wins(self) -> np.ndarray:
        return np.isin(self.outcome, ATTACKER_WIN_VALUES)

    def outcome_counts(self) -> dict[str, int]:
        return {o.label: int(np.sum(self.outcome == o)) for o in Outcome if o != Outcome.RUNNING}


def play(config: GameConfig, players: dict[str, Controller], positions: np.ndarray, record: bool = False) -> GameResults:
    """Play one game per row of ``positions`` ``(N, 3, 3)`` until every game has ended."""
    game = BatchedGame(config, len(positions))
    game.reset(positions=positions)
    returns = np.zeros((game.num_games, len(AGENTS)))
    attacker_returns = np.zeros((game.num_games, 3))
    trajectory = [game.positions.copy()] if record else []
    while game.active.any():
        actions = np.stack([players[agent].act(game) for agent in AGENTS], axis=1)
        result = game.step(actions)
        returns += result.rewards
        attacker_returns += result.attacker_rewards
        if record:
            trajectory.append(game.positions.copy())
    return GameResults(game.outcome.copy(), game.steps.copy(), returns, trajectory, attacker_returns)


def scripted_players(attacker: str, targeter: str, defender: str) -> dict[str, Controller]:
    return {
        "attacker": ScriptedPlayer("attacker", attacker),
        "targeter": ScriptedPlayer("targeter", targeter),
        "defender": ScriptedPlayer("defender", defender),
    }


def scripted_results(config: GameConfig, positions: np.ndarray) -> Iterator[tuple[str, str, str, GameResults]]:
    """Every scripted attacker against every scripted team on ``positions``, one matchup at a time."""
    for attacker in PLAYERS["attacker"]:
        for targeter in PLAYERS["targeter"]:
            for defender in PLAYERS["defender"]:
                players = scripted_players(attacker, targeter, defender)
                yield attacker, targeter, defender, play(config, players, positions)


def scripted_table(config: GameConfig, episodes: int, games: str = "dev") -> list[tuple[str, str, str, float, dict[str, int]]]:
    """Attacker win rate of every scripted attacker against every scripted team on the fixed ``games``."""
    positions = evaluation_scenarios(config.scenario, episodes, games)
    return [
        (attacker, targeter, defender, float(result.attacker_wins.mean()), result.outcome_counts())
        for attacker, targeter, defender, result in scripted_results(config, positions)
    ]


def package_version() -> str:
    """The installed package's version (pyproject.toml's), or why there is none."""
    try:
        return importlib.metadata.version(DISTRIBUTION)
    except importlib.metadata.PackageNotFoundError:
        return f"unknown ({DISTRIBUTION} is not installed: pip install -e .)"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m envs.match", description="Scripted-vs-scripted attacker win rates on fixed seeded games."
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {package_version()}")
    parser.add_argument("--episodes", type=int, default=1000)
    parser.add_argument("--scenario", default="default", choices=sorted(SCENARIO_SETS))
    parser.add_argument("--games", default="dev", choices=sorted(GAME_SETS),
                        help="the fixed dev games or the held-out test games (default: dev)")
    parser.add_argument(
        "--by-class",
        action="store_true",
        help="the attacker win rate with its 95%% Wilson interval overall and on each start class "
        "(envs.start_classes), and the classes' counts",
    )
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error("--episodes must be at least 1")
    config = GameConfig(scenario=args.scenario)
    print(f"scenario {args.scenario!r}, {args.episodes} fixed {args.games} episodes per row")
    if args.by_class:
        return _print_by_class(config, args.episodes, args.games)
    print("| attacker | targeter | defender | attacker wins | captured | timeout | terminal_reached | attacker_intercepted |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for attacker, targeter, defender, rate, counts in scripted_table(config, args.episodes, args.games):
        c = counts
        print(
            f"| {attacker} | {targeter} | {defender} | {rate:.3f} | {c['captured']} | {c['timeout']} "
            f"| {c['terminal_reached']} | {c['attacker_intercepted']} |"
        )
    return 0


def _print_by_class(config: GameConfig, episodes: int, games: str) -> int:
    """The table with the attacker's win rate per start class beside the overall one, each with its
    95% Wilson interval ("-": no such start)."""
    positions = evaluation_scenarios(config.scenario, episodes, games)
    classes = classify(positions, config)
    counts = class_counts(classes)
    print("start classes (envs.start_classes): " + ", ".join(f"{c.value} {n}" for c, n in counts.items()))
    names = " | ".join(f"{c.value} ({counts[c]})" for c in StartClass)
    print(f"| attacker | targeter | defender | attacker wins | {names} |")
    print("| --- | --- | --- | --- |" + " --- |" * len(StartClass))
    for attacker, targeter, defender, result in scripted_results(config, positions):
        wins = result.attacker_wins
        cells = [_rate(wins), *("-" if not counts[c] else _rate(wins[classes == c.value]) for c in StartClass)]
        print(f"| {attacker} | {targeter} | {defender} | " + " | ".join(cells) + " |")
    return 0


def _rate(wins: np.ndarray) -> str:
    low, high = wilson_interval(int(wins.sum()), len(wins))
    return f"{wins.mean():.3f} [{low:.3f}, {high:.3f}]"


if __name__ == "__main__":
    sys.exit(main())

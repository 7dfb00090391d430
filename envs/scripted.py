"""Scripted players (``shared/design.md`` section 3), each acting on the whole batch.

A player maps the batched game state (a ``GameView``: a ``BatchedGame``, or games
decoded from their global states) to the direction it wants to fly, ``(N, 3)``;
``ScriptedPlayer.act`` turns that into an action in the game's action mode.

| role     | name                      | rule                                                       |
| -------- | ------------------------- | ---------------------------------------------------------- |
| attacker | ``pure_pursuit``          | fly at T                                                   |
| attacker | ``lead_intercept``        | fly at the point where T, at its current velocity, is met  |
| attacker | ``proportional_navigation`` | turn the velocity at N times the line-of-sight rate;     |
|          |                           | pure pursuit while T is behind A (no line-of-sight rate    |
|          |                           | turns A around then)                                       |
| attacker | ``evade_defender``        | fly straight away from D: never attacks, wins only when T  |
|          |                           | does not reach the terminal in time (plays for time)       |
| targeter | ``straight``              | fly at the terminal                                        |
| targeter | ``avoid_attacker``        | fly at the terminal if T gets into the terminal sphere     |
|          |                           | before A can get within its capture radius of T (the       |
|          |                           | Apollonius ball with both radii), else hide behind D       |
| targeter | ``avoid_oncoming_attacker`` | as ``avoid_attacker``, and fly at the terminal also while |
|          |                           | A's velocity has no component toward T (A is not coming)   |
| defender | ``pure_pursuit``          | fly at A                                                   |
| defender | ``bisector_intercept``    | fly to where A's straight path to T crosses the bisector   |
|          |                           | plane of A and D (D gets there no later than A)            |

The players from the differential games of simple motion (``envs.theory_players``, where
their formulas, sources and departures from the theory are):

| role     | name                      | rule                                                       |
| -------- | ------------------------- | ---------------------------------------------------------- |
| attacker | ``apollonius``            | fly at the first point of T's straight path home that A    |
|          |                           | reaches in time and D does not cut off (guards the         |
|          |                           | terminal); away from D if D cuts off every one             |
| targeter | ``active_defense``        | race home when the straight race is won, else fly at the   |
|          |                           | point nearest the terminal that T reaches before A and D   |
|          |                           | reaches before A                                           |
| defender | ``active_defense``        | fly at the saddle-point interception point of A on the     |
|          |                           | A/D bisector plane in front of T                           |
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from envs.agents import AGENTS, ATTACKER, DEFENDER, TARGETER
from envs.config import GameConfig
from envs.game_view import DecodedGames, GameView
from envs.geometry import lead_intercept, norm, unit
from envs.kinematics import heading_vectors, headings_of, wrap_to_pi
from envs.observations import decode_global_state
from envs.theory_players import attacker_apollonius, defender_active_defense, targeter_active_defense

# Proportional navigation gain (3 to 5 is the textbook range).
NAVIGATION_GAIN = 3.0
# How far behind D (seen from A) the avoiding targeter aims.
SHELTER_DISTANCE = 0.3


Direction = Callable[[GameView], np.ndarray]


def _velocities(game: GameView) -> np.ndarray:
    """Current velocities ``(N, 3, 3)``: speed times heading."""
    velocities: np.ndarray = heading_vectors(game.headings) * game.speeds[None, :, None]
    return velocities


def attacker_pure_pursuit(game: GameView) -> np.ndarray:
    direction: np.ndarray = game.positions[:, TARGETER] - game.positions[:, ATTACKER]
    return direction


def attacker_lead_intercept(game: GameView) -> np.ndarray:
    a, t = game.positions[:, ATTACKER], game.positions[:, TARGETER]
    aim = lead_intercept(a, game.config.v_attacker, t, _velocities(game)[:, TARGETER])
    direction: np.ndarray = aim - a
    return direction


def attacker_proportional_navigation(game: GameView) -> np.ndarray:
    velocity = _velocities(game)
    los = game.positions[:, TARGETER] - game.positions[:, ATTACKER]
    closing = velocity[:, TARGETER] - velocity[:, ATTACKER]
    los_rate = np.cross(los, closing) / np.sum(los * los, axis=1, keepdims=True)
    navigation = velocity[:, ATTACKER] + NAVIGATION_GAIN * np.cross(los_rate, velocity[:, ATTACKER])
    # With T behind A the line of sight may not turn at all (T dead astern: rate 0), and
    # navigation would fly A away from T: pursue instead.
    behind = np.sum(los * velocity[:, ATTACKER], axis=1) < 0
    return np.where(behind[:, None], los, navigation)


def attacker_evade_defender(game: GameView) -> np.ndarray:
    # Equal speeds and D's turn limits keep a fleeing A out of reach: a team wins only by
    # flying T to the terminal while A is away, which a team that has only met attackers
    # coming at T may never learn.
    direction: np.ndarray = game.positions[:, ATTACKER] - game.positions[:, DEFENDER]
    return direction


def targeter_straight(game: GameView) -> np.ndarray:
    return -game.positions[:, TARGETER]


def targeter_is_safe(game: GameView) -> np.ndarray:
    """``(N,)``: T flying straight at the terminal gets into its sphere before A can capture it.

    T aims at ``E``, the nearest point of the terminal sphere. A can be within its capture
    radius ``r`` of a point ``P`` of T's path no sooner than ``(|P - A| - r) / v_A``, T is
    there at ``|P - T| / v_T``; the difference ``v_T (|P - A| - r) - v_A |P - T|`` only
    shrinks along the path (its slope is at most ``v_T - v_A < 0``), so T is safe when it
    is positive at ``E``: the Apollonius ball of T against A with both radii. Turn limits
    only slow A, so a safe T flying straight is never captured.
    """
    cfg = game.config
    a, t = game.positions[:, ATTACKER], game.positions[:, TARGETER]
    to_terminal = norm(t)
    goal = t * (cfg.terminal_sphere_radius / np.maximum(to_terminal, cfg.terminal_sphere_radius))[:, None]
    margin = cfg.v_targeter * (norm(goal - a) - cfg.attacker_radius) - cfg.v_attacker * norm(goal - t)
    return (to_terminal <= cfg.terminal_sphere_radius) | (margin > 0)


def targeter_avoid_attacker(game: GameView) -> np.ndarray:
    a, t, d = game.positions[:, ATTACKER], game.positions[:, TARGETER], game.positions[:, DEFENDER]
    shelter = d + SHELTER_DISTANCE * unit(d - a)
    return np.where(targeter_is_safe(game)[:, None], -t, shelter - t)


def targeter_avoid_oncoming_attacker(game: GameView) -> np.ndarray:
    # An attacker that flies away (evade_defender, playing for time) is not a threat: hiding
    # from it behind a D that chases it draws T away from the terminal until time runs out.
    a, t = game.positions[:, ATTACKER], game.positions[:, TARGETER]
    oncoming = np.sum((t - a) * _velocities(game)[:, ATTACKER], axis=1) > 0
    return np.where(oncoming[:, None], targeter_avoid_attacker(game), -t)


def defender_pure_pursuit(game: GameView) -> np.ndarray:
    direction: np.ndarray = game.positions[:, ATTACKER] - game.positions[:, DEFENDER]
    return direction


def defender_bisector_intercept(game: GameView) -> np.ndarray:
    a, t, d = game.positions[:, ATTACKER], game.positions[:, TARGETER], game.positions[:, DEFENDER]
    path = t - a
    offset = a - d
    # P = A + s (T - A) with |P - A| = |P - D|  =>  s = -|A - D|^2 / (2 (A - D).(T - A)).
    denom = 2.0 * np.sum(offset * path, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = -np.sum(offset * offset, axis=1) / denom
    reachable = (denom < 0) & (s <= 1.0)  # the crossing lies between A and T
    crossing = a + s[:, None] * path
    direction: np.ndarray = np.where(reachable[:, None], crossing - d, offset)
    return direction


PLAYERS: dict[str, dict[str, Direction]] = {
    "attacker": {
        "pure_pursuit": attacker_pure_pursuit,
        "lead_intercept": attacker_lead_intercept,
        "proportional_navigation": attacker_proportional_navigation,
        "evade_defender": attacker_evade_defender,
        "apollonius": attacker_apollonius,
    },
    "targeter": {
        "straight": targeter_straight,
        "avoid_attacker": targeter_avoid_attacker,
        "avoid_oncoming_attacker": targeter_avoid_oncoming_attacker,
        "active_defense": targeter_active_defense,
    },
    "defender": {
        "pure_pursuit": defender_pure_pursuit,
        "bisector_intercept": defender_bisector_intercept,
        "active_defense": defender_active_defense,
    },
}
# The paper's training opponents of the attacker (section 5).
PAPER_TEAM = {"targeter": "avoid_attacker", "defender": "pure_pursuit"}


def direction_to_action(game: GameView, agent: int, direction: np.ndarray) -> np.ndarray:
    """Action ``(N, 2)`` in the game's action mode that turns ``agent`` toward ``direction``."""
    cfg = game.config
    current = game.headings[:, agent]
    desired = headings_of(direction, fallback_yaw=current[:, 0])
    if cfg.action_mode == "absolute":
        return desired
    yaw = wrap_to_pi(desired[:, 0] - current[:, 0]) / cfg.max_yaw_change
    pitch = (desired[:, 1] - current[:, 1]) / cfg.max_pitch_change
    action: np.ndarray = np.clip(np.stack((yaw, pitch), axis=1), -1.0, 1.0)
    return action


def act_from_state(config: GameConfig, agent: str, name: str, states: np.ndarray) -> np.ndarray:
    """Actions ``(N, 2)`` of a scripted player that sees only global states ``(N, 22)``.

    For hosts that hold observations rather than a ``BatchedGame`` (an RLlib module).
    """
    positions, headings, _ = decode_global_state(config, states)
    return ScriptedPlayer(agent, name).act(DecodedGames(config, positions, headings))


@dataclass(frozen=True)
class ScriptedPlayer:
    """A named scripted player for one agent."""

    agent: str
    name: str

    def __post_init__(self) -> None:
        if self.agent not in PLAYERS:
            raise ValueError(f"unknown agent {self.agent!r}; expected one of {AGENTS}")
        if self.name not in PLAYERS[self.agent]:
            raise ValueError(f"unknown scripted {self.agent} {self.name!r}; expected one of {sorted(PLAYERS[self.agent])}")

    def act(self, game: GameView) -> np.ndarray:
        direction = PLAYERS[self.agent][self.name](game)
        return direction_to_action(game, AGENTS.index(self.agent), direction)

"""The differential-game players (``envs.theory_players``) on hand-built starts."""

import numpy as np
import pytest

from envs.agents import ATTACKER, DEFENDER, TARGETER, Outcome
from envs.config import GameConfig
from envs.core import BatchedGame
from envs.geometry import angle_between, norm
from envs.kinematics import headings_of
from envs.match import scripted_players
from envs.start_classes import race_margin
from envs.theory_players import defender_active_defense, home_path_meeting, targeter_active_defense


def straight_home_starts(n: int, seed: int = 0) -> np.ndarray:
    """T 2 to 3.5 from the terminal, A 1 to 2.5 from T, D 40 away (out of play)."""
    rng = np.random.default_rng(seed)

    def directions() -> np.ndarray:
        v = rng.normal(size=(n, 3))
        return v / np.linalg.norm(v, axis=1, keepdims=True)

    t = directions() * rng.uniform(2.0, 3.5, (n, 1))
    a = t + directions() * rng.uniform(1.0, 2.5, (n, 1))
    return np.stack((a, t, t + directions() * 40.0), axis=1)


def game_at(config: GameConfig, positions: np.ndarray, aims: dict[int, np.ndarray]) -> BatchedGame:
    """A game at ``positions`` with each agent of ``aims`` heading at its point, the others at T."""
    game = BatchedGame(config, len(positions))
    game.reset(positions=positions)
    headings = np.stack([headings_of(positions[:, TARGETER] - positions[:, i]) for i in range(3)], axis=1)
    for agent, point in aims.items():
        headings[:, agent] = headings_of(point - positions[:, agent])
    game.headings = headings
    return game


def test_the_apollonius_attacker_meets_a_straight_flying_targeter_where_its_path_home_leaves_its_region():
    config = GameConfig()
    positions = straight_home_starts(300)
    probe = game_at(config, positions, {})
    rho, flight = home_path_meeting(probe)
    caught = rho < flight - 0.5  # T cannot race home, and the meeting is well before the terminal
    positions, rho = positions[caught], rho[caught]
    assert len(positions) > 100
    t = positions[:, TARGETER]
    predicted = t - rho[:, None] * t / norm(t)[:, None]
    game = game_at(config, positions, {ATTACKER: predicted, TARGETER: np.zeros_like(t)})
    players = scripted_players("apollonius", "straight", "pure_pursuit")
    before = game.positions[:, TARGETER].copy()  # T at the start of the step that ends each game
    while game.active.any():
        before[game.active] = game.positions[game.active, TARGETER]
        game.step(np.stack([players[agent].act(game) for agent in ("attacker", "targeter", "defender")], axis=1))
    assert np.all(game.outcome == Outcome.CAPTURED)
    # T is caught on a step whose chord passes within the capture radius of the predicted point
    # (the game keeps the end of the step, up to 0.13 past the contact).
    chord = game.positions[:, TARGETER] - before
    along = np.clip(np.sum((predicted - before) * chord, axis=1) / np.sum(chord * chord, axis=1), 0.0, 1.0)
    assert np.max(norm(before + along[:, None] * chord - predicted)) < config.attacker_radius


def test_the_active_defense_targeter_flies_straight_home_on_a_t_race_start():
    config = GameConfig()
    # A 1.2 behind T and flying at it, D far away: T wins the straight race home.
    positions = np.array([[[3.8, 0.6, 0.0], [2.6, 0.0, 0.0], [2.6, -40.0, 0.0]]])
    assert race_margin(positions, config)[0] > 0
    game = game_at(config, positions, {TARGETER: np.zeros((1, 3))})
    np.testing.assert_allclose(targeter_active_defense(game), -positions[:, TARGETER])
    players = scripted_players("lead_intercept", "active_defense", "active_defense")
    path = [game.positions[0, TARGETER].copy()]
    while game.active.any():
        game.step(np.stack([players[agent].act(game) for agent in ("attacker", "targeter", "defender")], axis=1))
        path.append(game.positions[0, TARGETER].copy())
    assert game.outcome[0] == Outcome.TERMINAL_REACHED
    # Every step on the line from T's start to the terminal, and nearer the terminal.
    path = np.array(path)
    assert np.max(norm(np.cross(path, path[0] / norm(path[0])))) < 1e-9 and np.all(np.diff(norm(path)) < 0)


def test_the_active_defense_targeter_does_not_race_a_start_it_loses():
    config = GameConfig()
    positions = np.array([[[1.5, 0.3, 0.0], [3.0, 0.0, 0.0], [3.0, 1.5, 0.0]]])  # A between T and the terminal
    assert race_margin(positions, config)[0] < 0
    game = game_at(config, positions, {})  # A flies at T
    direction = targeter_active_defense(game)[0]
    assert angle_between(direction, -positions[0, TARGETER]) > 0.5
    assert direction[1] > 0  # toward D's side


def brute_force_interception(config: GameConfig, positions: np.ndarray) -> np.ndarray:
    """``argmin |I - T| + k |I - A|`` over a fine grid of the bisector plane of ``A`` and ``D_r``."""
    a, t, d = positions[ATTACKER], positions[TARGETER], positions[DEFENDER]
    d_reach = d + config.defender_radius * (a - d) / norm(a - d)
    middle, normal = 0.5 * (a + d_reach), (a - d_reach) / norm(a - d_reach)
    e1 = np.cross(normal, [0.0, 0.0, 1.0])
    e1 /= norm(e1)
    e2 = np.cross(normal, e1)
    x, y = np.meshgrid(np.linspace(-4, 4, 1601), np.linspace(-4, 4, 1601))
    grid = middle + x[..., None] * e1 + y[..., None] * e2
    k = config.v_targeter / config.v_attacker
    cost = norm(grid - t) + k * norm(grid - a)
    return grid.reshape(-1, 3)[np.argmin(cost)]


@pytest.mark.parametrize(
    "positions",
    [
        [[0.0, 2.0, 0.0], [2.5, 0.0, 0.5], [3.0, 1.5, -0.4]],
        [[-1.0, -1.5, 1.0], [1.0, 0.5, 0.0], [0.5, -1.0, 0.2]],
    ],
)
def test_the_active_defense_defender_heads_at_the_saddle_point_interception_point(positions):
    config = GameConfig(action_mode="absolute")
    positions = np.array([positions])
    expected = brute_force_interception(config, positions[0])
    game = game_at(config, positions, {})
    aim = positions[0, DEFENDER] + defender_active_defense(game)[0]
    assert norm(aim - expected) < 0.01  # the grid's spacing is 0.005
    # Its action turns D's heading at the point.
    heading = scripted_players("apollonius", "active_defense", "active_defense")["defender"].act(game)[0]
    np.testing.assert_allclose(heading, headings_of((expected - positions[0, DEFENDER])[None])[0], atol=0.01)

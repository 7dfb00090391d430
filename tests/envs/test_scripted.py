"""Scripted players: their geometry, and the balance of the default scenarios."""

import numpy as np
import pytest

from envs.agents import AGENTS, ATTACKER, DEFENDER, TARGETER, Outcome
from envs.config import GameConfig
from envs.core import BatchedGame
from envs.geometry import apollonius_ball, lead_intercept, norm
from envs.kinematics import headings_of
from envs.match import play, scripted_players
from envs.scenarios import evaluation_scenarios
from envs.scripted import (
    PAPER_TEAM,
    PLAYERS,
    ScriptedPlayer,
    defender_bisector_intercept,
    targeter_avoid_attacker,
    targeter_avoid_oncoming_attacker,
    targeter_is_safe,
)


def test_lead_intercept_meets_a_constant_velocity_target():
    rng = np.random.default_rng(0)
    chaser, target = rng.normal(size=(100, 3)), rng.normal(size=(100, 3))
    velocity = rng.normal(size=(100, 3))
    velocity *= 0.13 / np.linalg.norm(velocity, axis=1, keepdims=True)
    aim = lead_intercept(chaser, 0.18, target, velocity)
    t_chaser = norm(aim - chaser) / 0.18
    t_target = norm(aim - target) / 0.13
    np.testing.assert_allclose(t_chaser, t_target, rtol=1e-9)


def test_apollonius_ball_boundary_is_equal_time():
    slow, fast, k = np.array([[1.0, 0, 0]]), np.array([[-1.0, 0, 0]]), 0.5
    centre, radius = apollonius_ball(slow, fast, k)
    point = centre + radius[:, None] * np.array([[0.0, 1.0, 0.0]])
    assert norm(point - slow)[0] == pytest.approx(k * norm(point - fast)[0])


def test_bisector_intercept_point_is_equidistant():
    game = BatchedGame(GameConfig(), 1)
    game.reset(positions=np.array([[[0.0, 0, 0], [4.0, 0, 0], [2.0, 1.0, 0]]]))
    direction = defender_bisector_intercept(game)
    crossing = game.positions[0, DEFENDER] + direction[0]
    assert crossing[1] == pytest.approx(0.0) and 0 < crossing[0] < 4  # on A's path to T
    a_dist = norm(crossing - game.positions[0, ATTACKER])
    d_dist = norm(crossing - game.positions[0, DEFENDER])
    assert a_dist == pytest.approx(d_dist)


def test_avoiding_targeter_goes_straight_when_safe_and_hides_otherwise():
    game = BatchedGame(GameConfig(), 2)
    game.reset(
        positions=np.array(
            [
                [[5.0, 5.0, 0], [0.5, 0, 0], [2.0, 2.0, 0]],  # A far away: terminal in T's ball
                [[-1.0, 0, 0], [1.0, 0, 0], [1.0, 1.0, 0]],  # A between T and the terminal
            ]
        )
    )
    direction = targeter_avoid_attacker(game)
    np.testing.assert_allclose(direction[0], -game.positions[0, TARGETER])
    assert direction[1, 1] > 0  # toward D's side, away from A


def test_the_targeter_hides_only_from_an_oncoming_attacker():
    game = BatchedGame(GameConfig(), 2)
    unsafe = [[-1.0, 0, 0], [1.0, 0, 0], [1.0, 1.0, 0]]  # A between T and the terminal
    game.reset(positions=np.array([unsafe, unsafe]))
    game.headings[:, ATTACKER] = [[np.pi, 0.0], [0.0, 0.0]]  # A flies away from T (-x), then toward T (+x)
    direction = targeter_avoid_oncoming_attacker(game)
    np.testing.assert_allclose(direction[0], -game.positions[0, TARGETER])  # home
    np.testing.assert_allclose(direction[1], targeter_avoid_attacker(game)[1])  # hides, as avoid_attacker
    assert direction[1, 1] > 0


def straight_line_starts(n, seed=0):
    """T 1 to 3 from the terminal heading straight at it, A 0.5 to 3 from T heading at T, D far away."""
    rng = np.random.default_rng(seed)

    def directions():
        v = rng.normal(size=(n, 3))
        return v / np.linalg.norm(v, axis=1, keepdims=True)

    t = directions() * rng.uniform(1.0, 3.0, (n, 1))
    a = t + directions() * rng.uniform(0.5, 3.0, (n, 1))
    d = t + directions() * 40.0
    game = BatchedGame(GameConfig(), n)
    game.reset(positions=np.stack((a, t, d), axis=1))
    game.headings = np.stack((headings_of(t - a), headings_of(-t), headings_of(a - d)), axis=1)
    return game


def play_on(game, players):
    while game.active.any():
        game.step(np.stack([players[agent].act(game) for agent in AGENTS], axis=1))
    return game.outcome


@pytest.mark.parametrize("attacker", sorted(PLAYERS["attacker"]))
def test_a_targeter_called_safe_is_never_captured(attacker):
    game = straight_line_starts(500)
    safe = targeter_is_safe(game)
    assert safe.sum() > 150
    outcome = play_on(game, scripted_players(attacker, "avoid_attacker", "pure_pursuit"))
    assert not np.any(safe & (outcome == Outcome.CAPTURED))


def test_the_apollonius_ball_without_the_capture_radius_is_not_safe():
    # The terminal inside T's Apollonius ball (radii left out) is not enough: flying straight
    # against the lead-intercept attacker (the best reply to a straight flight), some are caught.
    game = straight_line_starts(500)
    a, t = game.positions[:, ATTACKER], game.positions[:, TARGETER]
    centre, radius = apollonius_ball(t, a, 0.13 / 0.18)
    ball_safe = norm(centre) < radius
    outcome = play_on(game, scripted_players("lead_intercept", "straight", "pure_pursuit"))
    assert np.sum(ball_safe & (outcome == Outcome.CAPTURED)) > 5


def test_proportional_navigation_turns_around_for_a_target_behind():
    # T dead astern of A on A's own line of flight: the line of sight does not turn, so
    # navigation alone would fly A away and let T through to the terminal.
    positions = np.array([[[-1.5, 0.0, 0.0], [-3.0, 0.0, 0.0], [0.0, 30.0, 0.0]]])
    result = play(GameConfig(), scripted_players("proportional_navigation", "straight", "pure_pursuit"), positions)
    assert result.outcome[0] == Outcome.CAPTURED


def test_the_evading_attacker_wins_only_by_the_time_limit():
    # It never attacks and D (as fast as A) never catches it: a targeter flying straight gets
    # through every time; one that hides behind D while A is near runs out of time in some.
    config, positions = GameConfig(), evaluation_scenarios("default", 300)
    straight = play(config, scripted_players("evade_defender", "straight", "pure_pursuit"), positions)
    assert np.all(straight.outcome == Outcome.TERMINAL_REACHED)
    hiding = play(config, scripted_players("evade_defender", "avoid_attacker", "pure_pursuit"), positions)
    assert not np.any(hiding.outcome == Outcome.ATTACKER_INTERCEPTED)
    assert np.sum(hiding.outcome == Outcome.TIMEOUT) > 20


@pytest.mark.parametrize("agent, names", sorted(PLAYERS.items()))
def test_every_scripted_player_gives_valid_actions(agent, names):
    for action_mode in ("relative", "absolute"):
        game = BatchedGame(GameConfig(action_mode=action_mode), 64)
        game.reset(np.random.default_rng(0))
        for name in names:
            actions = ScriptedPlayer(agent, name).act(game)
            assert actions.shape == (64, 2) and np.all(np.isfinite(actions))


def test_unknown_scripted_player():
    with pytest.raises(ValueError, match="expected one of"):
        ScriptedPlayer("attacker", "teleport")


def test_default_scenarios_are_balanced():
    config = GameConfig()
    players = scripted_players("lead_intercept", PAPER_TEAM["targeter"], PAPER_TEAM["defender"])
    result = play(config, players, evaluation_scenarios(config.scenario, 1000))
    assert 0.2 <= result.attacker_wins.mean() <= 0.8


@pytest.mark.parametrize("agent", ["attacker", "targeter", "defender"])
def test_scripted_players_act_the_same_from_the_global_state(agent):
    from envs.scripted import act_from_state

    config = GameConfig()
    game = BatchedGame(config, 32)
    game.reset(np.random.default_rng(4))
    for _ in range(3):
        game.step(np.random.default_rng(5).uniform(-1, 1, (32, 3, 2)))
    for name in PLAYERS[agent]:
        expected = ScriptedPlayer(agent, name).act(game)
        np.testing.assert_allclose(act_from_state(config, agent, name, game.global_state()), expected, atol=1e-4)


def test_evaluation_games_are_prefix_stable():
    np.testing.assert_array_equal(evaluation_scenarios("default", 1000)[:37], evaluation_scenarios("default", 37))
    np.testing.assert_array_equal(evaluation_scenarios("default", 500)[200:300], evaluation_scenarios("default", 300)[200:])

"""Captures over the whole step, every outcome, tie order and the episode end."""

import numpy as np
import pytest

from envs.agents import ATTACKER, DEFENDER, TARGETER, Outcome
from envs.config import GameConfig
from envs.core import BatchedGame
from envs.geometry import first_contact
from envs.match import play, scripted_players

STRAIGHT = np.zeros((1, 3, 2))  # relative mode: no turn


def game_at(positions, yaws=(0.0, 0.0, 0.0), **overrides):
    game = BatchedGame(GameConfig(**overrides), 1)
    game.reset(positions=np.asarray([positions], dtype=float))
    game.headings[0, :, 0] = yaws
    return game


def test_swept_capture_catches_a_head_on_pass_that_end_of_step_checks_miss():
    # A flies +x, T flies -x, 0.15 apart sideways: they pass each other within one step.
    game = game_at([[-0.1, 0.0, 0.0], [0.1, 0.15, 0.0], [-3.0, 3.0, 0.0]], yaws=(0.0, np.pi, 0.0))
    game.time_limit[:] = 100
    result = game.step(STRAIGHT)
    end_distance = np.linalg.norm(game.positions[0, ATTACKER] - game.positions[0, TARGETER])
    assert end_distance > game.config.attacker_radius  # an end-of-step check sees no capture
    assert result.outcome[0] == Outcome.CAPTURED
    assert result.done[0]


def test_swept_capture_of_the_attacker_by_the_defender():
    game = game_at([[0.1, 0.15, 0.0], [3.0, 3.0, 0.0], [-0.1, 0.0, 0.0]], yaws=(np.pi, 0.0, 0.0))
    game.time_limit[:] = 100
    result = game.step(STRAIGHT)
    assert np.linalg.norm(game.positions[0, DEFENDER] - game.positions[0, ATTACKER]) > game.config.defender_radius
    assert result.outcome[0] == Outcome.ATTACKER_INTERCEPTED


def test_first_contact_time_and_miss():
    tau = first_contact(np.array([[1.0, 0, 0], [1.0, 1.0, 0]]), np.array([[-1.0, 0, 0], [-1.0, 1.0, 0]]), 0.5)
    assert tau[0] == pytest.approx(0.25)
    assert np.isinf(tau[1])


def test_earliest_event_wins():
    # Head-on, D reaches A at about tau = 0.28 of the step, A would reach T at about 0.97.
    game = game_at([[0.0, 0.0, 0.0], [0.45, -0.1, 0.0], [0.25, 0.1, 0.0]], yaws=(0.0, np.pi, np.pi))
    game.time_limit[:] = 100
    assert game.step(STRAIGHT).outcome[0] == Outcome.ATTACKER_INTERCEPTED


def test_on_a_tie_the_attackers_capture_counts():
    # T is inside the terminal sphere and inside A's capture radius at the same instant.
    game = game_at([[0.0, 0.1, 0.0], [0.0, 0.0, 0.0], [0.0, 0.27, 0.0]])
    assert game.step(STRAIGHT).outcome[0] == Outcome.CAPTURED


def test_terminal_reached():
    game = game_at([[-3.0, 3.0, 0.0], [-0.2, 0.0, 0.0], [-3.0, -3.0, 0.0]])
    result = game.step(STRAIGHT)
    assert result.outcome[0] == Outcome.TERMINAL_REACHED


def test_timeout_after_gamma_steps():
    # T flies straight away from the terminal; nobody can catch anybody.
    game = game_at([[-3.0, 3.0, 0.0], [2.0, 0.0, 0.0], [-3.0, -3.0, 0.0]], yaws=(np.pi, 0.0, np.pi))
    gamma = int(np.ceil(2 * 2.0 / 0.13))
    assert game.time_limit[0] == gamma
    for _ in range(gamma - 1):
        assert not game.step(STRAIGHT).done[0]
    result = game.step(STRAIGHT)
    assert result.done[0] and result.outcome[0] == Outcome.TIMEOUT
    assert Outcome.TIMEOUT.attacker_wins


def test_finished_games_stay_frozen_while_others_run():
    game = BatchedGame(GameConfig(), 2)
    game.reset(
        positions=np.array(
            [[[-3.0, 3, 0], [-0.2, 0, 0], [-3, -3, 0]], [[-3.0, 3, 0], [2.0, 0, 0], [-3, -3, 0]]], dtype=float
        )
    )
    first = game.step(np.zeros((2, 3, 2)))
    assert first.done.tolist() == [True, False]
    frozen = game.positions[0].copy()
    second = game.step(np.zeros((2, 3, 2)))
    np.testing.assert_array_equal(game.positions[0], frozen)
    assert second.rewards[0].tolist() == [0.0, 0.0, 0.0]
    assert not second.done[0] and game.outcome[0] == Outcome.TERMINAL_REACHED


def test_every_outcome_is_reached_by_scripted_play():
    config = GameConfig()
    from envs.scenarios import evaluation_scenarios

    seen = set()
    for attacker, targeter in (("lead_intercept", "straight"), ("pure_pursuit", "avoid_attacker")):
        result = play(config, scripted_players(attacker, targeter, "pure_pursuit"), evaluation_scenarios("default", 300))
        seen |= {Outcome(int(o)) for o in result.outcome}
        assert np.all(result.outcome != Outcome.RUNNING)
    assert seen == {Outcome.CAPTURED, Outcome.TIMEOUT, Outcome.TERMINAL_REACHED, Outcome.ATTACKER_INTERCEPTED}


@pytest.mark.parametrize("terminal_reward", [0.0, 1.0])
def test_terminal_reward_goes_to_the_winner(terminal_reward):
    plain = game_at([[-3.0, 3.0, 0.0], [-0.2, 0.0, 0.0], [-3.0, -3.0, 0.0]])
    bonus = game_at([[-3.0, 3.0, 0.0], [-0.2, 0.0, 0.0], [-3.0, -3.0, 0.0]], terminal_reward=terminal_reward)
    difference = bonus.step(STRAIGHT).rewards - plain.step(STRAIGHT).rewards
    np.testing.assert_allclose(difference[0], [-terminal_reward, terminal_reward, terminal_reward])

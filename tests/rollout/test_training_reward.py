"""How a learner is paid in training (``league.rollout.training_reward``), checked by hand on
two games of three steps, without Ray or torch.

| step | game 0                   | game 1                         |
| ---- | ------------------------ | ------------------------------ |
| 0    | running                  | running                        |
| 1    | A captures T (A wins)    | running                        |
| 2    | running (a new game)     | D intercepts A (the team wins) |
"""

import numpy as np
import pytest
from pydantic import ValidationError

from envs.agents import AGENTS, Outcome
from envs.config import GameConfig
from envs.observations import GLOBAL_STATE_SIZE, STATE_D_ATTACKER, STATE_T_TERMINAL
from league.config import RunConfig
from league.rollout.games import Rows
from league.rollout.training_reward import TrainingPay, ended_steps, learner_rewards, method_rewards

GAME = GameConfig()
SCALE = GAME.position_scale
OUTCOMES = np.array([[0, 0], [int(Outcome.CAPTURED), 0], [0, int(Outcome.ATTACKER_INTERCEPTED)]])
BY_METHOD = np.arange(18, dtype=np.float64).reshape(3, 2, 3)  # (step, game, method): method m's reward 3 (2 t + g) + m - 1
OWN = {"attacker": [[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]], "targeter": [[0.5, -0.5], [1.5, 0.0], [0.0, 2.5]],
       "defender": [[-1.0, 0.25], [2.0, 0.0], [0.0, -3.0]]}
# Global states before each step and after the last: T's distance to the terminal and D's to A, in position units.
T_TERMINAL = np.array([[10.0, 20.0], [8.0, 18.0], [30.0, 15.0], [29.0, 12.0]])
D_ATTACKER = np.array([[5.0, 6.0], [4.0, 5.0], [7.0, 3.0], [6.0, 9.0]])


def rows() -> Rows:
    observations = {agent: np.zeros((2, 3 + GLOBAL_STATE_SIZE), dtype=np.float32) for agent in AGENTS}
    played = Rows(observations, capacity=3)
    for agent in AGENTS:
        played.rewards[agent][:] = OWN[agent]
        played.observations[agent][:, :, 3 + STATE_T_TERMINAL] = T_TERMINAL / SCALE
        played.observations[agent][:, :, 3 + STATE_D_ATTACKER] = D_ATTACKER / SCALE
    played.outcome[:] = OUTCOMES
    played.attacker_rewards[:] = BY_METHOD
    return played


def pay(**changes) -> TrainingPay:
    plain = dict(reward_method=None, gamma=0.9, lambda_=0.95, targeter_shaping=0.0, defender_shaping=0.0,
                 attacker_win_reward=0.0, team_reward="own")
    return TrainingPay(**{**plain, **changes})


def test_the_attacker_is_paid_the_reward_of_its_own_method():
    for method in (1, 2, 3):
        expected = 3 * (2 * np.arange(3)[:, None] + np.arange(2)[None, :]) + method - 1
        np.testing.assert_array_equal(method_rewards(BY_METHOD, method), expected)
        np.testing.assert_array_equal(learner_rewards(pay(reward_method=method), "attacker", rows(), 3, GAME), expected)
    # One step's info, as the batched sampler's connector reads it.
    assert method_rewards(np.array([0.1, 0.2, 0.3]), 2) == 0.2


def test_the_win_reward_is_paid_on_the_step_a_game_ends():
    paid = learner_rewards(pay(reward_method=2, attacker_win_reward=70.0), "attacker", rows(), 3, GAME)
    np.testing.assert_array_equal(paid - method_rewards(BY_METHOD, 2), [[0.0, 0.0], [70.0, 0.0], [0.0, -70.0]])
    np.testing.assert_array_equal(ended_steps(OUTCOMES), [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])


def test_t_and_d_are_paid_their_own_or_the_shared_reward():
    for agent in ("targeter", "defender"):
        np.testing.assert_array_equal(learner_rewards(pay(), agent, rows(), 3, GAME), OWN[agent])
        shared = learner_rewards(pay(team_reward="shared"), agent, rows(), 3, GAME)
        np.testing.assert_array_equal(shared, np.add(OWN["targeter"], OWN["defender"]))


@pytest.mark.parametrize(("agent", "distances"), [("targeter", T_TERMINAL), ("defender", D_ATTACKER)])
def test_shaping_pays_the_change_of_potential_and_no_other_agent(agent, distances):
    k, gamma = 3.0, 0.9
    shaped = learner_rewards(pay(**{f"{agent}_shaping": k}), agent, rows(), 3, GAME)
    # Phi = -k d; 0 after a game's end (game 0 after step 1, game 1 after step 2).
    after = np.where(OUTCOMES != 0, 0.0, -k * distances[1:])
    np.testing.assert_allclose(shaped - np.array(OWN[agent]), gamma * after + k * distances[:-1], rtol=1e-6)
    other = "defender" if agent == "targeter" else "targeter"
    np.testing.assert_array_equal(learner_rewards(pay(**{f"{agent}_shaping": k}), other, rows(), 3, GAME), OWN[other])


def test_a_run_pays_each_side_as_its_settings_say():
    run = RunConfig(name="pay", ppo={"team_gamma": 0.999, "targeter_shaping": 30.0, "defender_shaping": 3.0,
                                     "team_reward": "shared", "attacker_win_reward": 70.0,
                                     "attacker_win_reward_methods": [2, 3]})
    assert TrainingPay.of(run, "team") == pay(gamma=0.999, lambda_=run.ppo.lambda_, targeter_shaping=30.0,
                                              defender_shaping=3.0, team_reward="shared")
    assert TrainingPay.of(run, "attacker", 3) == pay(reward_method=3, gamma=run.ppo.gamma, lambda_=run.ppo.lambda_,
                                                     attacker_win_reward=70.0)
    assert TrainingPay.of(run, "attacker", 1).attacker_win_reward == 0.0  # method 1 is not listed


def test_a_misspelt_or_ill_typed_pay_setting_is_an_error_naming_it():
    with pytest.raises(ValidationError, match="targeter_shapng"):
        pay(targeter_shapng=3.0)
    with pytest.raises(ValidationError, match="team_reward"):
        pay(team_reward="shard")

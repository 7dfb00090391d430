"""The priors (``ppo.attacker_prior``, ``ppo.team_prior``): with a network that outputs
nothing, the policy's mean is exactly the scripted player's action."""

import numpy as np
import onnxruntime
import pytest
import torch

from envs.agents import ATTACKER, DEFENDER, TARGETER
from envs.core import BatchedGame
from envs.kinematics import heading_vectors
from envs.observations import global_state, observe, policy_input
from envs.scripted import ScriptedPlayer, targeter_is_safe
from league.config import load_config
from league.evaluation.exported_policy import ExportedPolicy, export
from league.rllib.bridge import learner_spec
from league.rllib.ppo_loss import LOG_SQRT_2PI, PPOCoefficients, ppo_loss
from ray.rllib.core.columns import Columns
from ray.rllib.evaluation.postprocessing import Postprocessing


def attacker_with_prior(run):
    return learner_spec(run, "attacker", reward_method=2).build()


def silence(module):
    head = module.pi.net[-1]
    torch.nn.init.zeros_(head.weight)
    torch.nn.init.zeros_(head.bias)
    return module


def turned_anywhere(run):
    rng = np.random.default_rng(0)
    game = BatchedGame(run.game, 4096)
    game.reset(rng)
    # Turned anywhere, not only as the games start: yaw all round, pitch within its limits.
    game.headings[:] = np.stack((rng.uniform(0, 2 * np.pi, (4096, 3)), rng.uniform(-1.2, 1.2, (4096, 3))), axis=-1)
    return game


def assert_plays(module, run, game, agent, name):
    time_left = np.ones(game.num_games)
    obs = policy_input(observe(run.game, game.positions, game.headings, time_left, agents=[agent])[0],
                       global_state(run.game, game.positions, game.headings, time_left))
    expected = ScriptedPlayer(("attacker", "targeter", "defender")[agent], name).act(game)
    with torch.no_grad():
        actual = module.deterministic_action(torch.from_numpy(obs)).numpy()
    # The observation is float32: positions of order 10 carry ~1e-6 rounding, and the turn
    # divides angles by limits of order 1, so 1e-4 is ample (the largest difference is ~2e-6).
    np.testing.assert_allclose(actual, expected, atol=1e-4)
    assert (np.abs(expected) < 1).mean() > 0.4 and np.abs(expected).max() == 1.0  # turns both within and at the limits


@pytest.mark.parametrize("prior", ["lead_intercept", "apollonius"])
def test_an_attacker_with_a_prior_and_a_silent_network_plays_that_scripted_attacker(prior):
    run = load_config("selfplay_league", [f"ppo.attacker_prior={prior}"])
    game = turned_anywhere(run)
    if prior == "apollonius":  # it turns otherwise than lead intercept in many of these games
        lead, apollonius = (ScriptedPlayer("attacker", name).act(game) for name in ("lead_intercept", "apollonius"))
        assert (np.abs(apollonius - lead).max(axis=1) > 1e-3).mean() > 0.2
    assert_plays(silence(attacker_with_prior(run)), run, game, ATTACKER, prior)


def test_a_team_with_the_prior_and_a_silent_network_flies_t_home_and_d_at_a():
    run = load_config("selfplay_league", ["ppo.team_prior=straight+pure_pursuit"])
    team, game = silence(learner_spec(run, "team").build()), turned_anywhere(run)
    assert_plays(team, run, game, TARGETER, "straight")
    assert_plays(team, run, game, DEFENDER, "pure_pursuit")


@pytest.mark.parametrize("targeter", ["avoid_attacker", "avoid_oncoming_attacker"])
def test_a_team_with_an_avoiding_prior_and_a_silent_network_plays_that_scripted_team(targeter):
    run = load_config("selfplay_league", [f"ppo.team_prior={targeter}+pure_pursuit"])
    team, game = silence(learner_spec(run, "team").build()), turned_anywhere(run)
    safe = targeter_is_safe(game)
    a, t = game.positions[:, ATTACKER], game.positions[:, TARGETER]
    oncoming = np.sum((t - a) * heading_vectors(game.headings)[:, ATTACKER], axis=1) > 0
    # T flies home in some games and hides in others; unsafe games with A flying away tell the two apart
    assert 0.05 < safe.mean() < 0.95 and 0.05 < (~safe & ~oncoming).mean() and 0.05 < (~safe & oncoming).mean()
    assert_plays(team, run, game, TARGETER, targeter)
    assert_plays(team, run, game, DEFENDER, "pure_pursuit")


def correction_after_updates(run, penalty):
    """The mean square of the attacker network's correction of lead intercept before and after 30 Adam steps on
    a batch whose advantages are all zero: PPO's surrogate gives the actor no gradient, so only the penalty moves it."""
    torch.manual_seed(0)
    module = attacker_with_prior(run)
    torch.nn.init.normal_(module.pi.net[-1].weight, std=0.3)  # a correction to pull back
    game = turned_anywhere(run)
    time_left = np.ones(game.num_games)
    obs = torch.from_numpy(policy_input(observe(run.game, game.positions, game.headings, time_left, agents=[ATTACKER])[0],
                                        global_state(run.game, game.positions, game.headings, time_left)))
    with torch.no_grad():
        dist_inputs = module.action_dist_inputs(obs)
        mean, log_std = dist_inputs.chunk(2, dim=-1)
        logp = (-log_std - LOG_SQRT_2PI).sum(-1)  # the mean's own log-probability
    zeros = torch.zeros(len(obs))
    batch = {Columns.OBS: obs, Columns.ACTIONS: mean, Columns.ACTION_LOGP: logp, Columns.ACTION_DIST_INPUTS: dist_inputs,
             Postprocessing.ADVANTAGES: zeros, Postprocessing.VALUE_TARGETS: zeros}
    coefficients = PPOCoefficients(clip_param=0.2, vf_clip_param=float("inf"), vf_loss_coeff=0.5, entropy_coeff=0.0,
                                   kl_coeff=None, residual_penalty=penalty)
    optimizer = torch.optim.Adam(module.parameters(), lr=1e-3)

    def square():
        with torch.no_grad():
            return module.prior_correction(obs)[1].pow(2).sum(-1).mean().item()

    before = square()
    for _ in range(30):
        optimizer.zero_grad()
        ppo_loss(module, batch, coefficients)[0].backward()
        optimizer.step()
    return before, square()


def test_the_residual_penalty_pulls_the_attacker_back_to_its_prior():
    run = load_config("attacker_method2", [])
    before, after = correction_after_updates(run, penalty=1.0)
    assert before > 0.05 and after < before / 2
    assert correction_after_updates(run, penalty=0.0) == (before, before)  # no penalty: the actor stays as it was


def test_the_gated_penalty_weighs_only_the_steps_before_t_turns_away():
    run = load_config("attacker_method2", ["game.attacker_memory=true"])
    torch.manual_seed(0)
    module = attacker_with_prior(run)
    torch.nn.init.normal_(module.pi.net[-1].weight, std=0.3)
    game = turned_anywhere(run)
    time_left, memory = np.ones(game.num_games), np.where(np.arange(game.num_games) % 3 == 0, 0.5, 0.0)  # a third turned
    own = observe(run.game, game.positions, game.headings, time_left, agents=[ATTACKER], targeter_turned_away=memory)[0]
    obs = torch.from_numpy(policy_input(own, global_state(run.game, game.positions, game.headings, time_left)))
    with torch.no_grad():
        dist_inputs = module.action_dist_inputs(obs)
        square = module.prior_correction(obs)[1].pow(2).sum(-1)
        assert torch.equal(module.prior_correction(obs)[0], dist_inputs)  # the loss's one pass gives the policy's inputs
    zeros = torch.zeros(len(obs))
    batch = {Columns.OBS: obs, Columns.ACTIONS: dist_inputs[:, :2], Columns.ACTION_LOGP: zeros,
             Columns.ACTION_DIST_INPUTS: dist_inputs, Postprocessing.ADVANTAGES: zeros, Postprocessing.VALUE_TARGETS: zeros}

    def loss(penalty, gated):
        coefficients = PPOCoefficients(clip_param=0.2, vf_clip_param=float("inf"), vf_loss_coeff=0.5, entropy_coeff=0.0,
                                       kl_coeff=None, residual_penalty=penalty, residual_penalty_gated=gated)
        with torch.no_grad():
            return ppo_loss(module, batch, coefficients)[0].item()

    straight = torch.from_numpy(memory == 0.0)
    # The penalty's part of the loss: float32 sums of 4096 rows of order 0.1 agree to ~1e-5.
    assert loss(2.0, False) - loss(0.0, False) == pytest.approx(2.0 * square.mean().item(), abs=1e-4)
    assert loss(2.0, True) - loss(0.0, False) == pytest.approx(2.0 * (square * straight).mean().item(), abs=1e-4)
    assert (square * ~straight).mean().item() > 0.01  # the rows left out carry a correction the gate spares


@pytest.mark.parametrize("fmt", ["export", "torchscript", "onnx"])
@pytest.mark.parametrize("side", ["attacker", "team"])
def test_the_priors_and_the_attackers_features_travel_in_every_export_format(tmp_path, fmt, side):
    run = load_config("selfplay_league", ["ppo.attacker_prior=apollonius", "ppo.attacker_heading_cosines=true",
                                          "ppo.attacker_scripted_turns=true", "ppo.team_prior=avoid_oncoming_attacker+pure_pursuit"])
    module = learner_spec(run, side, reward_method=2 if side == "attacker" else None).build()
    rng = np.random.default_rng(1)
    game = BatchedGame(run.game, 256)
    game.reset(rng)
    agents = [ATTACKER] if side == "attacker" else [TARGETER, DEFENDER]
    obs = np.concatenate(observe(run.game, game.positions, game.headings, np.ones(256), agents=agents))
    out = tmp_path / f"{side}.{fmt}"
    export(ExportedPolicy(module.pi, module.actor_inputs).eval(), {"observation": {"size": obs.shape[1]}}, fmt, out)
    if fmt == "onnx":
        actions = onnxruntime.InferenceSession(str(out)).run(None, {"observation": obs})[0]
    else:
        policy = torch.export.load(out).module() if fmt == "export" else torch.jit.load(out)
        actions = policy(torch.from_numpy(obs)).detach().numpy()
    with torch.no_grad():
        expected = module.pi(torch.from_numpy(obs)).numpy()
    # float32 actions of size ~1: another kernel or order changes only the last of ~7 digits.
    np.testing.assert_allclose(actions, expected, atol=1e-5)

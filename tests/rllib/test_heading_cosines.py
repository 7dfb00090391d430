"""The attacker's two heading cosines (``ppo.attacker_heading_cosines``) and its scripted attackers'
turns (``ppo.attacker_scripted_turns``): what they measure, and that the attacker's network reads
them where asked, the team's never."""

import numpy as np
import torch

from envs.agents import ATTACKER, DEFENDER, TARGETER
from envs.core import BatchedGame
from envs.kinematics import heading_vectors
from envs.observations import observe
from envs.scripted import ScriptedPlayer
from league.config import load_config
from league.rllib.bridge import learner_spec
from league.rllib.modules import HeadingCosines, ScriptedTurns


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_the_cosines_are_those_of_the_headings_against_the_lines_to_the_goals():
    run = load_config("selfplay_league")
    rng = np.random.default_rng(0)
    game = BatchedGame(run.game, 1024)
    game.reset(rng)
    game.headings[:] = np.stack((rng.uniform(0, 2 * np.pi, (1024, 3)), rng.uniform(-1.2, 1.2, (1024, 3))), axis=-1)
    own = observe(run.game, game.positions, game.headings, np.ones(1024), agents=[ATTACKER])[0]

    with torch.no_grad():
        out = HeadingCosines()(torch.from_numpy(own)).numpy()

    vectors = heading_vectors(game.headings)
    positions = game.positions  # the terminal is the origin
    expected_t = (vectors[:, TARGETER] * unit(-positions[:, TARGETER])).sum(-1)
    expected_d = (vectors[:, DEFENDER] * unit(positions[:, ATTACKER] - positions[:, DEFENDER])).sum(-1)
    np.testing.assert_array_equal(out[:, : own.shape[1]], own)  # the observation, unchanged, first
    # float32 observations of lengths ~1 carry ~1e-7 relative rounding; a cosine of them, ~1e-6.
    np.testing.assert_allclose(out[:, -2], expected_t, atol=1e-5)
    np.testing.assert_allclose(out[:, -1], expected_d, atol=1e-5)
    assert out[:, -2].min() < -0.9 and out[:, -2].max() > 0.9  # headings all round: both signs


def test_only_the_attackers_network_reads_them():
    run = load_config("selfplay_league", ["ppo.attacker_heading_cosines=true"])
    attacker = learner_spec(run, "attacker", reward_method=1).build()
    team = learner_spec(run, "team").build()
    net = attacker.pi.net  # lead intercept's prior plus this network
    assert isinstance(net[0], HeadingCosines) and net[1].in_features == attacker.actor_inputs + 2
    assert not any(isinstance(layer, HeadingCosines) for layer in team.pi.modules())

    # A straight-flying T and one flying off: the same observation but for T's heading.
    obs = torch.zeros(2, attacker.observation_space.shape[0])
    obs[:, 1] = 1.0  # A level: cos pitch 1
    obs[:, 2:6] = torch.tensor([1.0, 0.0, 0.0, 1.0])  # T one length ahead of A
    obs[:, 9:13] = torch.tensor([-1.0, 0.0, 0.0, 1.0])  # D one length behind A
    obs[:, 16:20] = torch.tensor([3.0, 0.0, 0.0, 3.0])  # the terminal three lengths ahead of A
    obs[0, 6] = 1.0  # T flies at the terminal
    obs[1, 6] = -1.0  # T flies back, toward A
    with torch.no_grad():
        cosines = net[0](attacker.actor_features(obs))[:, -2:]
    torch.testing.assert_close(cosines, torch.tensor([[1.0, 0.0], [-1.0, 0.0]]))


def test_the_scripted_turns_are_lead_intercepts_and_the_apollonius_attackers_read_after_the_cosines():
    run = load_config("selfplay_league", ["ppo.attacker_heading_cosines=true", "ppo.attacker_scripted_turns=true"])
    attacker, team = learner_spec(run, "attacker", reward_method=2).build(), learner_spec(run, "team").build()
    features = attacker.pi.net[0]  # lead intercept's prior plus this network
    assert [type(part) for part in features] == [HeadingCosines, ScriptedTurns]
    assert attacker.pi.net[1].in_features == attacker.actor_inputs + 2 + 4
    assert not any(isinstance(layer, ScriptedTurns) for layer in team.pi.modules())
    rng = np.random.default_rng(0)
    game = BatchedGame(run.game, 1024)
    game.reset(rng)
    own = observe(run.game, game.positions, game.headings, np.ones(1024), agents=[ATTACKER])[0]
    with torch.no_grad():
        out = features(torch.from_numpy(own)).numpy()
    np.testing.assert_array_equal(out[:, : own.shape[1]], own)
    with torch.no_grad():
        np.testing.assert_array_equal(out[:, own.shape[1] : own.shape[1] + 2], HeadingCosines()(torch.from_numpy(own))[:, -2:].numpy())
    # float32 observations: the turns agree with the float64 scripted players to ~1e-6 (tests/rllib/test_priors.py).
    np.testing.assert_allclose(out[:, -4:-2], ScriptedPlayer("attacker", "lead_intercept").act(game), atol=1e-4)
    np.testing.assert_allclose(out[:, -2:], ScriptedPlayer("attacker", "apollonius").act(game), atol=1e-4)

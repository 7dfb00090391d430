"""The learners' modules (``league.rllib.modules``): the team's centralized critic and the attacker's local one."""

import pytest
import torch
from ray.rllib.core.columns import Columns

from league.config import RunConfig
from league.rllib.bridge import learner_spec


@pytest.fixture(scope="module")
def modules():
    run = RunConfig(name="t", ppo={"hidden": [16, 16]})
    return {side: learner_spec(run, side).build() for side in ("attacker", "team")}


def test_team_critic_reads_the_global_state_and_the_role_and_the_actor_does_not(modules):
    team = modules["team"]
    own = team.actor_inputs
    obs = torch.randn(8, team.observation_space.shape[0])
    assert obs.shape[1] - own == 22  # the appended global state
    obs[:, own - 2 : own] = torch.tensor([1.0, 0.0])  # all targeters
    other_own = obs.clone()
    other_own[:, : own - 2] = torch.randn(8, own - 2)  # same role, different own view
    other_state = obs.clone()
    other_state[:, own:] = torch.randn(8, 22)
    other_role = obs.clone()
    other_role[:, own - 2 : own] = torch.tensor([0.0, 1.0])  # the defenders at the same global state
    values = team.compute_values({Columns.OBS: obs})
    torch.testing.assert_close(team.compute_values({Columns.OBS: other_own}), values)
    assert not torch.allclose(team.compute_values({Columns.OBS: other_state}), values)
    assert not torch.allclose(team.compute_values({Columns.OBS: other_role}), values)
    actions = team.deterministic_action(obs)
    torch.testing.assert_close(team.deterministic_action(other_state), actions)
    assert not torch.allclose(team.deterministic_action(other_own), actions)


def test_team_critic_learns_different_values_for_t_and_d_at_one_state():
    """T and D are paid differently (Eq. 10, 11): at the same global state the critic must
    be able to fit both returns, which a critic blind to the role cannot (it fits their mean)."""
    torch.manual_seed(0)
    team = learner_spec(RunConfig(name="t", ppo={"hidden": [16, 16]}), "team").build()
    own = team.actor_inputs
    state = torch.randn(64, team.observation_space.shape[0])
    targeters, defenders = state.clone(), state.clone()
    targeters[:, own - 2 : own] = torch.tensor([1.0, 0.0])
    defenders[:, own - 2 : own] = torch.tensor([0.0, 1.0])
    obs = torch.cat((targeters, defenders))
    returns = torch.cat((torch.full((64,), -1.0), torch.full((64,), 1.0)))
    optimizer = torch.optim.Adam(team.vf.parameters(), lr=1e-2)
    for _ in range(300):
        loss = (team.compute_values({Columns.OBS: obs}) - returns).pow(2).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    # Blind to the role, the best fit is 0 for every row: a squared error of 1.
    assert loss.item() < 0.01


def test_attacker_critic_is_local(modules):
    attacker = modules["attacker"]
    obs = torch.randn(8, attacker.observation_space.shape[0])
    other_state = obs.clone()
    other_state[:, attacker.actor_inputs :] = torch.randn(8, 22)
    torch.testing.assert_close(attacker.compute_values({Columns.OBS: other_state}), attacker.compute_values({Columns.OBS: obs}))

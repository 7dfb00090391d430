"""The ceiling for training speed: a minimal plain-PyTorch PPO on the same game core.

CleanRL-style, one file, no Ray: the config's attacker against its first scripted team,
played by ``league.rollout.games`` (the games and step loop of the fast sampler), with the network, batch,
minibatch, epochs and loss of the league's PPO (``league.rllib``): a Gaussian policy with a
state-independent log-std and a separate value network (``league.rllib.modules.mlp``), GAE
(``league.rollout.train_batch``), standardised advantages, the clipped surrogate, the value
loss, the entropy bonus and RLlib's adaptive KL penalty (coefficient 0.2, target 0.01),
gradients clipped by global norm. ``bench/train_throughput.py`` runs it beside the
league's samplers; ``python bench/plain_ppo.py --env-steps N`` runs it alone.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch
from torch import nn

from envs.vector_env import TargetDefenseVectorEnv
from league.config import RunConfig, load_config
from league.rllib.modules import INITIAL_LOG_STD, mlp
from league.rollout.games import Rollout, ScriptedOnState
from league.rollout.train_batch import gae, standardized
from league.rollout.training_reward import ended_steps, method_rewards

KL_COEFF, KL_TARGET = 0.2, 0.01  # RLlib's PPO defaults, which the league's PPO keeps


class Agent(nn.Module):
    def __init__(self, observations: int, hidden: list[int]):
        super().__init__()
        self.pi = mlp(observations, hidden, 2, last_gain=0.01)
        self.log_std = nn.Parameter(torch.full((2,), INITIAL_LOG_STD))
        self.vf = mlp(observations, hidden, 1, last_gain=1.0)

    def dist(self, obs: torch.Tensor) -> torch.distributions.Normal:
        return torch.distributions.Normal(self.pi(obs), self.log_std.exp())


def train_plain(run: RunConfig, env_steps: int) -> dict:
    """Train the attacker for at least ``env_steps``; env-steps/s after one warm-up iteration."""
    torch.manual_seed(run.seed)
    ppo, games = run.ppo, run.resources.num_envs_per_env_runner
    team = run.league.scripted_teams[0]
    rollout = Rollout(TargetDefenseVectorEnv(run.game.model_dump(), games), lambda agent, episode_id: agent)
    rollout.reset(seed=run.seed)
    method = run.game.attacker_reward
    obs_size = rollout.observations["attacker"].shape[1]
    agent = Agent(obs_size, ppo.hidden)

    def attacker(obs: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        with torch.no_grad():
            dist = agent.dist(torch.from_numpy(obs))
            action = dist.sample()
        return action.numpy(), {"logp": dist.log_prob(action).sum(-1).numpy()}

    policies = {"attacker": attacker, "targeter": ScriptedOnState(team.targeter), "defender": ScriptedOnState(team.defender)}
    optimizer = torch.optim.Adam(agent.parameters(), lr=ppo.lr)
    kl_coeff = KL_COEFF
    rows = -(-ppo.train_batch_size // games)
    steps, start, iteration = 0, None, 0
    rng = np.random.default_rng(run.seed)
    while steps < env_steps:
        played, _, _, _ = rollout.play(
            rows, None, lambda r, t: rollout.act_by_module(r, t, policies.__getitem__), on_game_end=lambda *_: None,
            observed=lambda: ("attacker",),  # the scripted team acts on the games' state
        )
        observations = played.observations["attacker"]  # rows + 1: the last one is bootstrapped
        actions, logps = played.actions["attacker"], played.outputs[("attacker", "logp")].astype(np.float64)
        rewards = method_rewards(played.attacker_rewards, method)  # the game's reward, no training extras
        ended = ended_steps(played.outcome)
        with torch.no_grad():
            values = agent.vf(torch.from_numpy(observations)).squeeze(-1).numpy().astype(np.float64)
        advantages, targets = gae(rewards, values[:-1], values[-1], ended, ppo.gamma, ppo.lambda_)
        batch = {
            "obs": torch.from_numpy(observations[:-1].reshape(-1, obs_size)),
            "actions": torch.from_numpy(actions.reshape(-1, 2)),
            "logp": torch.from_numpy(logps.reshape(-1)).float(),
            "advantages": torch.from_numpy(standardized(advantages.reshape(-1))).float(),
            "targets": torch.from_numpy(targets.reshape(-1)).float(),
        }
        with torch.no_grad():
            old = agent.dist(batch["obs"])
        size = len(batch["obs"])
        kls = []
        for _ in range(ppo.num_epochs):
            order = rng.permutation(size)
            for first in range(0, size, ppo.minibatch_size):
                rows_ = torch.from_numpy(order[first : first + ppo.minibatch_size])
                dist = agent.dist(batch["obs"][rows_])
                logp = dist.log_prob(batch["actions"][rows_]).sum(-1)
                ratio = torch.exp(logp - batch["logp"][rows_])
                advantage = batch["advantages"][rows_]
                surrogate = torch.min(advantage * ratio, advantage * ratio.clamp(1 - ppo.clip_param, 1 + ppo.clip_param))
                previous = torch.distributions.Normal(old.loc[rows_], old.scale[rows_])
                kl = torch.distributions.kl_divergence(previous, dist).sum(-1).mean()
                value_loss = (agent.vf(batch["obs"][rows_]).squeeze(-1) - batch["targets"][rows_]).pow(2).mean()
                loss = (
                    -surrogate.mean()
                    + ppo.vf_loss_coeff * value_loss
                    - ppo.entropy_coeff * dist.entropy().sum(-1).mean()
                    + kl_coeff * kl
                )
                optimizer.zero_grad()
                loss.backward()
                if ppo.grad_clip:
                    nn.utils.clip_grad_norm_(agent.parameters(), ppo.grad_clip)
                optimizer.step()
                kls.append(kl.item())
        mean_kl = float(np.mean(kls))
        if mean_kl > 2.0 * KL_TARGET:  # RLlib's adaptive KL coefficient
            kl_coeff *= 1.5
        elif mean_kl < 0.5 * KL_TARGET:
            kl_coeff *= 0.5
        iteration += 1
        if start is None:  # after the warm-up iteration, as the league's samplers are timed
            start = time.perf_counter()
        else:
            steps += rows * games
    wall = time.perf_counter() - start
    return {"rate": steps / wall, "steps": steps, "wall": wall, "agent": agent}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="smoke")
    parser.add_argument("--set", dest="overrides", action="append", default=[], help="key=value config override")
    parser.add_argument("--env-steps", type=int, default=200_000)
    args = parser.parse_args()
    run = load_config(args.config, args.overrides)
    torch.set_num_threads(run.resources.threads_for(1))
    result = train_plain(run, args.env_steps)
    print(f"plain PPO: {result['rate']:.0f} env-steps/s ({result['steps']} env steps in {result['wall']:.1f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""End-to-end training speed of the league's samplers, against plain PyTorch PPO as the ceiling.

``python bench/train_throughput.py`` trains the attacker of each named config (default:
smoke and attacker_method2) against its first scripted team, once per sampler
(``--samplers``, default ``fast batched``: the arrays straight to the Learner, and RLlib's
standard learner path fed by the same batched games; ``standard``, RLlib's own env
runner, is slow and so not run by default), everything else equal, for the same number of
env steps; then ``bench/plain_ppo.py`` with the same network, batch and loss. For each:

* env-steps/s over the whole training after one warm-up iteration, timed here by wall
  clock (RLlib's own timers are smoothed averages), and the mean seconds per iteration;
* when the attacker's training win rate (over its last ``--window`` episodes) first
  reached ``--target``, in seconds and env steps;
* the trained attacker's win rate against the scripted team on 1000 fixed evaluation
  games, with a 95% Wilson interval: the samplers should land in the same band.

The last line per config reads ``fast F env-steps/s, standard S env-steps/s, plain P
env-steps/s, fast/plain R`` (``standard``: the ``batched`` sampler's RLlib learner path). With
``--repeats N`` each config runs its samplers and plain PPO in turn N times (the same seed, so
the same training: only the timing differs) and the line gives the medians, R the median of the
N ratios of a fast run to the plain run after it, with their range: on a 2-core AMD EPYC plain
PPO on ``attacker_method1`` ran 30,824 and 34,750 env-steps/s over 1,000,000 env steps on two tries
in a row.
"""

from __future__ import annotations

import argparse
import time
from collections import deque

import numpy as np
import ray
import torch

from envs.match import play
from envs.scenarios import evaluation_scenarios
from envs.observations import split_policy_input
from envs.scripted import ScriptedPlayer
from league.config import RunConfig, load_config
from league.evaluation.engine import LearnedAgent
from league.analysis.statistics import wilson_interval
from league.core.payoff import attacker_won
from league.core.players import Player
from league.core.match_plan import MatchPlan
from league.rllib.bridge import build_config, episode_outcomes, set_trainable

from plain_ppo import train_plain  # bench/ beside this file

EVALUATION_GAMES = 1000


def train(run: RunConfig, env_steps: int, target: float, window: int) -> dict:
    """Train the attacker against the scripted team for ``env_steps``; speed and win rates."""
    method = run.game.attacker_reward
    attacker = Player(id=1, side="attacker", kind="learner", version=0, reward_method=method)
    team_names = run.league.scripted_teams[0]
    team = Player(
        id=2, side="team", kind="scripted", version=0,
        scripted_targeter=team_names.targeter, scripted_defender=team_names.defender,
    )
    plan = MatchPlan([{"attacker": attacker.name}], [[team.modules()]], [[1.0]], seed=run.seed)
    algo = build_config(run, [attacker, team], plan).build_algo()
    set_trainable(algo, [attacker.name])
    algo.train()  # warm-up: first forward passes, Learner set-up

    recent: deque[bool] = deque(maxlen=window)
    steps = iterations = 0
    reached = None
    start = time.perf_counter()
    while steps < env_steps:
        result = algo.train()
        iterations += 1
        steps += result["env_runners"]["num_env_steps_sampled"]
        for _, outcome, count in episode_outcomes(result):
            recent.extend([attacker_won(outcome)] * count)
        if reached is None and len(recent) == window and np.mean(recent) >= target:
            reached = (time.perf_counter() - start, steps)
    wall = time.perf_counter() - start

    win_rate = evaluate(run, algo.get_module(attacker.name))
    algo.stop()
    return {"rate": steps / wall, "steps": steps, "wall": wall, "iteration": wall / iterations, "reached": reached, **win_rate}


def evaluate(run: RunConfig, policy: torch.nn.Module) -> dict:
    """Win rate of ``policy`` (with a ``deterministic_action``) against the scripted team on the fixed games."""
    team_names = run.league.scripted_teams[0]
    players = {
        "attacker": LearnedAgent(policy, "attacker"),
        "targeter": ScriptedPlayer("targeter", team_names.targeter),
        "defender": ScriptedPlayer("defender", team_names.defender),
    }
    games = play(run.game, players, evaluation_scenarios(run.game.scenario, EVALUATION_GAMES))
    wins = int(games.attacker_wins.sum())
    return {"win_rate": wins / EVALUATION_GAMES, "interval": wilson_interval(wins, EVALUATION_GAMES)}


class PlainPolicy(torch.nn.Module):
    """The plain PPO agent seen as the league's modules are: ``deterministic_action``."""

    def __init__(self, agent: torch.nn.Module):
        super().__init__()
        self.agent = agent

    def deterministic_action(self, obs: torch.Tensor) -> torch.Tensor:
        own = self.agent.pi[0].in_features  # plain PPO's actor reads the own observation only
        return self.agent.pi(split_policy_input(obs, own)[0])


def local_resources(run: RunConfig) -> dict:
    """A private Ray instance on this machine that can place every env runner of ``run``: a
    cluster config (``{sampler: 1}`` per runner) runs all its runners on this one node."""
    res = run.resources
    return {
        "num_cpus": max(res.num_cpus, int(np.ceil(res.num_env_runners * res.num_cpus_per_env_runner))),
        "resources": {name: amount * res.num_env_runners for name, amount in res.custom_resources_per_env_runner.items()},
    }


def line(name: str, r: dict, target: float) -> str:
    reached = f"{r['reached'][0]:.0f} s / {r['reached'][1]} env steps" if r.get("reached") else "not reached"
    low, high = r["interval"]
    timing = f"{r['steps']} env steps in {r['wall']:.0f} s" + (f", {r['iteration']:.2f} s per iteration" if "iteration" in r else "")
    return (
        f"{name:8s}: {r['rate']:.0f} env-steps/s ({timing}); training win rate {target}: {reached}; "
        f"vs scripted team on {EVALUATION_GAMES} games: {r['win_rate']:.3f} [{low:.3f}, {high:.3f}]"
    )


def summary(config: str, rates: dict[str, list[float]]) -> str:
    """The medians over the repeats, and fast/plain: the median of each repeat's ratio (a fast run over
    the plain run right after it, so that both met the machine's state of that moment), with its range."""
    fast, plain = rates.get("fast", []), rates["plain"]
    standard = rates.get("batched", rates.get("standard", [float("nan")]))
    ratios = [f / p for f, p in zip(fast, plain)] or [float("nan")]
    spread = f" (range {min(ratios):.2f} to {max(ratios):.2f} over {len(ratios)} repeats)" if len(ratios) > 1 else ""
    return (
        f"{config}: fast {np.median(fast or [float('nan')]):.0f} env-steps/s, standard {np.median(standard):.0f} env-steps/s, "
        f"plain {np.median(plain):.0f} env-steps/s, fast/plain {np.median(ratios):.2f}{spread}"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", nargs="+", default=["smoke", "attacker_method2"])
    parser.add_argument("--set", dest="overrides", action="append", default=[], help="key=value config override")
    parser.add_argument("--env-steps", type=int, default=300_000, help="training env steps per sampler")
    parser.add_argument("--standard-env-steps", type=int, help="fewer steps for the standard sampler (speed only)")
    parser.add_argument("--target", type=float, default=0.4, help="training win rate to time")
    parser.add_argument("--window", type=int, default=500, help="episodes behind the training win rate")
    parser.add_argument("--samplers", nargs="+", choices=["fast", "batched", "standard"], default=["fast", "batched"])
    parser.add_argument("--repeats", type=int, default=1,
                        help="times each config runs its samplers and plain PPO in turn (same seed: the same training, "
                             "so the repeats differ only in timing); medians reported")
    args = parser.parse_args()

    for config in args.configs:
        rates: dict[str, list[float]] = {}
        for _ in range(args.repeats):
            for sampler in args.samplers:
                # Only the attacker trains here; RLlib's own pipeline (batched, standard) has no team
                # discount, no shaping of T's rewards and no shared team reward.
                team = [] if sampler == "fast" else [
                    "ppo.team_gamma=null", "ppo.team_lambda_=null", "ppo.targeter_shaping=0", "ppo.team_reward=own",
                ]
                run = load_config(config, [*args.overrides, f"resources.sampler={sampler}", *team])
                torch.set_num_threads(run.resources.threads_for(1))
                steps = args.standard_env_steps or args.env_steps if sampler == "standard" else args.env_steps
                ray.init(address="local", include_dashboard=False, log_to_driver=False, **local_resources(run))
                try:
                    result = train(run, steps, args.target, args.window)
                finally:
                    ray.shutdown()
                rates.setdefault(sampler, []).append(result["rate"])
                print(f"{config} {line(sampler, result, args.target)}", flush=True)
            run = load_config(config, args.overrides)
            plain = train_plain(run, args.env_steps)
            rates.setdefault("plain", []).append(plain["rate"])
            print(f"{config} {line('plain', {**plain, **evaluate(run, PlainPolicy(plain['agent']))}, args.target)}", flush=True)
        print(summary(config, rates), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

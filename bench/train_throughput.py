"""End-to-end training speed of the fast (batched) and the standard RLlib sampler.

``python bench/train_throughput.py`` trains the attacker of a config (default: smoke)
against the scripted team, once with ``resources.sampler=batched`` and once with
``standard``, everything else equal, for the same number of env steps. For each it
prints:

* env-steps/s over the whole training (sampling plus learning, after one warm-up
  iteration), and the split of an iteration into sampling and learning;
* when the attacker's training win rate (over its last ``--window`` episodes) first
  reached ``--target``, in seconds and env steps;
* the trained attacker's win rate against the scripted team on 1000 fixed evaluation
  games, with a 95% Wilson interval: the two samplers should land in the same band.

The last line reads ``fast F env-steps/s, standard S env-steps/s, ratio R``.
"""

from __future__ import annotations

import argparse
import time
from collections import deque

import numpy as np
import ray

from envs.agents import Outcome
from envs.match import play
from envs.scenarios import evaluation_scenarios
from envs.scripted import ScriptedPlayer
from league.config import RunConfig, load_config
from league.evaluation import LearnedAgent, wilson_interval
from league.players import Player
from league.rllib_bridge import MatchPlan, build_config, match_counts, set_trainable

ATTACKER_WINS = {o.label for o in Outcome if o.attacker_wins}
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
    steps = 0
    sampling = learning = 0.0
    reached = None
    start = time.perf_counter()
    while steps < env_steps:
        result = algo.train()
        steps += result["env_runners"]["num_env_steps_sampled"]
        sampling += result["timers"]["env_runner_sampling_timer"]
        learning += result["timers"]["learner_update_timer"]
        for _, outcome, count in match_counts(result):
            recent.extend([outcome in ATTACKER_WINS] * count)
        if reached is None and len(recent) == window and np.mean(recent) >= target:
            reached = (time.perf_counter() - start, steps)
    wall = time.perf_counter() - start
    iterations = result["training_iteration"] - 1

    module = algo.get_module(attacker.name)
    players = {
        "attacker": LearnedAgent(module, "attacker"),
        "targeter": ScriptedPlayer("targeter", team_names.targeter),
        "defender": ScriptedPlayer("defender", team_names.defender),
    }
    games = play(run.game, players, evaluation_scenarios(run.game.scenario, EVALUATION_GAMES))
    wins = int(games.attacker_wins.sum())
    algo.stop()
    return {
        "rate": steps / wall,
        "steps": steps,
        "wall": wall,
        "sampling": sampling / max(iterations, 1),
        "learning": learning / max(iterations, 1),
        "reached": reached,
        "win_rate": wins / EVALUATION_GAMES,
        "interval": wilson_interval(wins, EVALUATION_GAMES),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="smoke")
    parser.add_argument("--set", dest="overrides", action="append", default=[], help="key=value config override")
    parser.add_argument("--env-steps", type=int, default=400_000, help="training env steps per sampler")
    parser.add_argument("--standard-env-steps", type=int, help="fewer steps for the standard sampler (speed only)")
    parser.add_argument("--target", type=float, default=0.4, help="training win rate to time")
    parser.add_argument("--window", type=int, default=500, help="episodes behind the training win rate")
    parser.add_argument("--samplers", nargs="+", choices=["batched", "standard"], default=["batched", "standard"])
    args = parser.parse_args()

    results = {}
    for sampler in args.samplers:
        run = load_config(args.config, [*args.overrides, f"resources.sampler={sampler}"])
        steps = args.env_steps if sampler == "batched" else (args.standard_env_steps or args.env_steps)
        ray.init(address="local", num_cpus=run.resources.num_cpus, include_dashboard=False, log_to_driver=False)
        try:
            results[sampler] = r = train(run, steps, args.target, args.window)
        finally:
            ray.shutdown()
        reached = (
            f"{r['reached'][0]:.0f} s / {r['reached'][1]} env steps" if r["reached"] else f"not within {r['steps']} env steps"
        )
        low, high = r["interval"]
        print(
            f"{sampler:8s}: {r['rate']:.0f} env-steps/s ({r['steps']} env steps in {r['wall']:.0f} s; per iteration "
            f"sampling {r['sampling']:.2f} s, learning {r['learning']:.2f} s); training win rate {args.target} reached: "
            f"{reached}; vs scripted team on {EVALUATION_GAMES} games: {r['win_rate']:.3f} [{low:.3f}, {high:.3f}]",
            flush=True,
        )
    if len(results) == 2:
        fast, standard = results["batched"]["rate"], results["standard"]["rate"]
        print(f"fast {fast:.0f} env-steps/s, standard {standard:.0f} env-steps/s, ratio {fast / standard:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

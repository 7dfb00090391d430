"""Evaluation episodes per second: batched workers against the RLlib env one game at a time.

``python bench/eval_speed.py --run-dir RUN --player attacker-m2-v1`` plays the player
against the paper's scripted team on the same fixed games three ways and prints
episodes/s for each: evaluation workers (Ray actors on the batched core), the batched
core in one process, and the RLlib ``MultiAgentEnv`` stepped one game at a time with
one module forward per step (what evaluating through RLlib's env API costs). The last
line reads ``workers W episodes/s, rllib env R episodes/s, ratio X``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import ray
import torch

from envs.agents import TARGETER
from envs.observations import observation_size, split_policy_input
from envs.rllib_env import TargetDefenseMultiAgentEnv
from envs.scenarios import evaluation_scenarios
from envs.scripted import PAPER_TEAM, act_from_state
from league.config import RunConfig, saved_run_config
from league.evaluation.engine import EvaluationPool, evaluate_pairs, load_module
from league.state.store import LeagueStore


def rllib_env_rate(run: RunConfig, module, positions: np.ndarray) -> float:
    env = TargetDefenseMultiAgentEnv({**run.game.model_dump(), "with_global_state": True})
    started = time.perf_counter()
    for start in positions:
        obs, _ = env.reset(options={"positions": start})
        done = False
        while not done:
            with torch.no_grad():
                attacker = module.deterministic_action(torch.from_numpy(obs["attacker"][None]))[0].numpy()
            state = split_policy_input(obs["targeter"][None], observation_size(run.game, TARGETER))[1]
            actions = {
                "attacker": attacker,
                "targeter": act_from_state(run.game, "targeter", PAPER_TEAM["targeter"], state)[0],
                "defender": act_from_state(run.game, "defender", PAPER_TEAM["defender"], state)[0],
            }
            obs, _, terminateds, _, _ = env.step(actions)
            done = terminateds["__all__"]
    return len(positions) / (time.perf_counter() - started)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run-dir", type=Path, required=True)
    parser.add_argument("--player", default="attacker-m2-v1")
    parser.add_argument("--episodes", type=int, default=1000)
    parser.add_argument("--rllib-episodes", type=int, default=200, help="games for the slow path")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()

    run = saved_run_config(args.run_dir)
    store = LeagueStore(args.run_dir)
    players = {p.name: p for p in store.players()}
    attacker, team = players[args.player], next(p for p in store.players() if p.is_paper_team)
    run_dir = args.run_dir.resolve()

    started = time.perf_counter()
    evaluate_pairs(run.game, run_dir, [(attacker, team)], args.episodes)
    local = args.episodes / (time.perf_counter() - started)
    print(f"batched core, one process: {local:.0f} episodes/s", flush=True)

    ray.init(address="local", num_cpus=args.workers, include_dashboard=False)
    pool = EvaluationPool(run.game, run_dir, args.workers, cpus_per_worker=1)
    pool.evaluate([(attacker, team)], 10)  # actors started, modules loaded
    started = time.perf_counter()
    pool.evaluate([(attacker, team)], args.episodes)
    workers = args.episodes / (time.perf_counter() - started)
    pool.close()
    ray.shutdown()
    print(f"evaluation workers ({args.workers}): {workers:.0f} episodes/s", flush=True)

    module = load_module(run_dir / attacker.checkpoint)
    rllib = rllib_env_rate(run, module, evaluation_scenarios(run.game.scenario, args.rllib_episodes))
    print(f"rllib env, one game at a time: {rllib:.1f} episodes/s", flush=True)
    print(f"workers {workers:.0f} episodes/s, rllib env {rllib:.1f} episodes/s, ratio {workers / rllib:.1f}")


if __name__ == "__main__":
    main()

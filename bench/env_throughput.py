"""Env-steps per second of the batched core and of the PettingZoo env, random actions.

``python bench/env_throughput.py`` prints one line per case, e.g.
``batched N=1024: 250000 env-steps/s``. One env-step is one game advanced by one step
(all three agents). Finished games are reset at once, as a sampler would.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from envs.config import GameConfig
from envs.core import BatchedGame
from envs.pettingzoo_env import TargetDefenseEnv


def batched_rate(config: GameConfig, num_games: int, seconds: float) -> float:
    rng = np.random.default_rng(0)
    game = BatchedGame(config, num_games)
    game.reset(rng)
    actions = rng.uniform(-1, 1, size=(256, num_games, 3, 2))
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        for i in range(16):
            game.step(actions[(steps + i) % 256])
            ended = np.flatnonzero(~game.active)
            if len(ended):
                game.reset_games(ended, rng)
        steps += 16
    return steps * num_games / (time.perf_counter() - start)


def pettingzoo_rate(config: GameConfig, seconds: float) -> float:
    env = TargetDefenseEnv(config)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        actions = {agent: rng.uniform(-1, 1, 2) for agent in env.agents}
        _, _, terminations, _, _ = env.step(actions)
        steps += 1
        if any(terminations.values()):
            env.reset()
    return steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0, help="time per case")
    parser.add_argument("--attacker-reward", type=int, default=2, choices=(1, 2, 3))
    args = parser.parse_args()
    config = GameConfig(attacker_reward=args.attacker_reward)
    for n in (1, 64, 1024):
        print(f"batched N={n}: {batched_rate(config, n, args.seconds):.0f} env-steps/s", flush=True)
    print(f"pettingzoo: {pettingzoo_rate(config, args.seconds):.0f} env-steps/s", flush=True)


if __name__ == "__main__":
    main()

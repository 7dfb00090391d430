"""Env-steps per second of the batched core and of the PettingZoo env, random actions.

``python bench/env_throughput.py`` prints one line per case, e.g.
``batched N=1024: 250000 env-steps/s (300000 per CPU-second)``. One env-step is one game
advanced by one step (all three agents). Finished games are reset at once, as a sampler
would. The per-CPU-second figure counts only this process's CPU time, so it moves less
than the wall-clock figure when other processes share the machine.

``python bench/env_throughput.py --against COMMIT`` compares this tree's batched core with
the one at ``COMMIT`` (its ``envs/`` exported with ``git archive``) at N = 1024: the two run
in turn, ``--rounds`` times each, in separate processes, and the ratio of their summed
rates is printed. Alternating spreads the machine's load over both alike.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from envs.config import GameConfig
from envs.core import BatchedGame
from envs.pettingzoo_env import TargetDefenseEnv

REPO = Path(__file__).resolve().parent.parent


def batched_rate(config: GameConfig, num_games: int, seconds: float) -> tuple[float, float]:
    """Env-steps per wall-clock second and per CPU-second of this process."""
    rng = np.random.default_rng(0)
    game = BatchedGame(config, num_games)
    game.reset(rng)
    actions = rng.uniform(-1, 1, size=(256, num_games, 3, 2))
    steps, start, cpu_start = 0, time.perf_counter(), time.process_time()
    while time.perf_counter() - start < seconds:
        for i in range(16):
            game.step(actions[(steps + i) % 256])
            ended = np.flatnonzero(~game.active)
            if len(ended):
                game.reset_games(ended, rng)
        steps += 16
    env_steps = steps * num_games
    return env_steps / (time.perf_counter() - start), env_steps / (time.process_time() - cpu_start)


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


# Run in a child process with the tree to measure first on the path (it has its own ``envs``).
_CHILD = """
import sys, numpy as np
sys.path.insert(0, sys.argv[1])
from envs.config import GameConfig
from envs.core import BatchedGame
exec(sys.argv[2])  # batched_rate's source, so both trees are timed by the same loop
print(*batched_rate(GameConfig(attacker_reward=int(sys.argv[3])), 1024, float(sys.argv[4])))
"""


def compare(commit: str, attacker_reward: int, seconds: float, rounds: int) -> None:
    import inspect

    source = "import time\n" + inspect.getsource(batched_rate).replace("-> tuple[float, float]", "")
    with tempfile.TemporaryDirectory() as baseline:
        archive = subprocess.run(["git", "-C", str(REPO), "archive", commit, "envs"], capture_output=True, check=True)
        subprocess.run(["tar", "-x", "-C", baseline], input=archive.stdout, check=True)
        totals = {commit: np.zeros(2), "this tree": np.zeros(2)}
        for _ in range(rounds):
            for name, tree in ((commit, baseline), ("this tree", str(REPO))):
                out = subprocess.run(
                    [sys.executable, "-c", _CHILD, tree, source, str(attacker_reward), str(seconds)],
                    capture_output=True, text=True, check=True, env={**os.environ, "PYTHONPATH": tree},
                )
                wall, cpu = map(float, out.stdout.split())
                totals[name] += (wall, cpu)
                print(f"{name}: batched N=1024: {wall:.0f} env-steps/s ({cpu:.0f} per CPU-second)", flush=True)
    old, new = totals[commit] / rounds, totals["this tree"] / rounds
    print(f"mean of {rounds}: {commit} {old[0]:.0f} env-steps/s ({old[1]:.0f} per CPU-second), "
          f"this tree {new[0]:.0f} ({new[1]:.0f}); ratio this / {commit}: {new[0] / old[0]:.3f} "
          f"(per CPU-second {new[1] / old[1]:.3f})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0, help="time per case")
    parser.add_argument("--attacker-reward", type=int, default=2, choices=(1, 2, 3))
    parser.add_argument("--against", metavar="COMMIT", help="compare the batched core with this commit's")
    parser.add_argument("--rounds", type=int, default=5, help="runs of each tree with --against")
    args = parser.parse_args()
    if args.against:
        compare(args.against, args.attacker_reward, args.seconds, args.rounds)
        return
    config = GameConfig(attacker_reward=args.attacker_reward)
    for n in (1, 64, 1024):
        wall, cpu = batched_rate(config, n, args.seconds)
        print(f"batched N={n}: {wall:.0f} env-steps/s ({cpu:.0f} per CPU-second)", flush=True)
    print(f"pettingzoo: {pettingzoo_rate(config, args.seconds):.0f} env-steps/s", flush=True)


if __name__ == "__main__":
    main()

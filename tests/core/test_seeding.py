"""Runs of different seeds, and the env runners of one run, draw no game start in common."""

import numpy as np

from envs.vector_env import TargetDefenseVectorEnv
from league.core.seeding import Purpose, stream_seed

GAMES = 512  # the shipped configs' games per env runner


def starts(seed: int, games: int = GAMES) -> set[bytes]:
    env = TargetDefenseVectorEnv({}, games)
    env.reset(seed=seed)
    return {row.tobytes() for row in env.core.positions}


def test_runs_of_neighbouring_seeds_share_no_game_start():
    seen: dict[bytes, tuple[int, int]] = {}
    for run_seed in range(6):
        for worker in range(3):
            for start in starts(stream_seed(run_seed, Purpose.GAME_STARTS, worker)):
                assert start not in seen, f"run seed {run_seed} runner {worker} replays {seen[start]}'s start"
                seen[start] = (run_seed, worker)
    assert len(seen) == 6 * 3 * GAMES


def test_plain_integer_seeds_would_share_them():
    # What the derived seeds replace: RLlib's seed + worker index, game i at that plus i.
    assert len(starts(0) & starts(1)) == GAMES - 1


def test_the_purpose_and_the_index_each_give_another_stream():
    seeds = {stream_seed(0, purpose, index) for purpose in Purpose for index in range(4)}
    assert len(seeds) == len(Purpose) * 4
    assert stream_seed(3, Purpose.GAME_STARTS, 1) == stream_seed(3, Purpose.GAME_STARTS, 1)
    assert all(0 <= s < 2**62 for s in seeds)

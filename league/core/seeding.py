"""Independent random streams of a run, each derived from (run seed, purpose, index).

Integer seeds such as ``seed + worker`` or ``seed + game`` make runs of neighbouring seeds
draw the same streams (run seed 1's game ``i`` was run seed 0's game ``i + 1``). Every
stream is instead drawn through ``numpy.random.SeedSequence``, whose hashing makes streams
of different entropy words independent; the purpose word keeps two uses of one seed apart.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np


class Purpose(IntEnum):
    """What a stream is for: one word of its ``SeedSequence`` entropy (values fixed: they make runs)."""

    GAME_STARTS = 1  # the training games' starting positions, per env runner
    EXPLORATION = 2  # torch's, NumPy's and Python's global generators (actions, minibatch order), per iteration and runner
    MATCH_PLANS = 3  # the coordinator's draws of each iteration's match-plan seed
    ORACLES = 4  # a double-oracle best response's training run (``league.double_oracle``), per self-play phase


def stream(seed: int, purpose: Purpose, *index: int) -> np.random.SeedSequence:
    """The ``SeedSequence`` of ``purpose``'s stream number ``index`` of a run seeded ``seed``."""
    return np.random.SeedSequence([seed, int(purpose), *index])


def run_seed(seed: int, purpose: Purpose, *index: int) -> int:
    """A seed in ``[0, 2**32)``, what a run's config takes (``RunConfig.seed``), from ``purpose``'s stream ``index``."""
    return int(stream(seed, purpose, *index).generate_state(1, np.uint32)[0])


def stream_seed(seed: int, purpose: Purpose, *index: int) -> int:
    """An integer seed in ``[0, 2**62)`` for APIs that take an integer: a window of ``seed + i``
    for ``i`` in the thousands starting from it meets another stream's window with odds of
    about one in ``2**50``."""
    high, low = stream(seed, purpose, *index).generate_state(2, np.uint32)
    return (int(high) << 30) | (int(low) >> 2)

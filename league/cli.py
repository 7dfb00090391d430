"""What the commands (``python -m league.run``, ``league.status``, ...) share: argument types and ``--version``.

A helper for commands, not a command: library code does not import it.
"""

from __future__ import annotations

import argparse
import sys
import time
from contextlib import nullcontext
from typing import IO

import league


def count(minimum: int):
    """An argparse type: an integer of at least ``minimum``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {value}")
        return value

    return parse


def mixture_seed(text: str) -> int:
    """An argparse type: a mixture player's seed (``league.core.mixture.SEED_RANGE``)."""
    from league.core.mixture import SEED_RANGE

    value = count(SEED_RANGE[0])(text)
    if value > SEED_RANGE[1]:
        raise argparse.ArgumentTypeError(f"must be at most {SEED_RANGE[1]}, got {value}")
    return value


MIXTURE_SEED_HELP = ("the seed from which a mixture player (nash-attacker, nash-team, @ITERATION) draws its member of "
                     "each game, with the game's index (default 0)")


def command_parser(prog: str, description: str, **kwargs) -> argparse.ArgumentParser:
    """A command's parser, with ``--version`` (the package's version)."""
    made = argparse.ArgumentParser(prog=prog, description=description, **kwargs)
    made.add_argument("--version", action="version", version=f"%(prog)s {league.__version__}")
    return made


class PairProgress:
    """A progress line on stderr as pairs are played: pairs done of all, time so far, time left at this pace.

    Called after each pair (``league.evaluation.engine.Progress``); prints for the first pair,
    the last, and at most one line every ``every_s`` seconds in between.
    """

    def __init__(self, what: str, every_s: float = 5.0, stream: IO[str] | None = None):
        self.what, self.every_s, self.stream = what, every_s, stream or sys.stderr
        self.start = self.last = time.monotonic()

    def __call__(self, done: int, total: int) -> None:
        now = time.monotonic()
        if done not in (1, total) and now - self.last < self.every_s:
            return
        self.last, elapsed = now, now - self.start
        left = f", about {elapsed / done * (total - done):.0f} s left" if done < total else ""
        print(f"{self.what}: {done} of {total} pairs, {elapsed:.0f} s{left}", file=self.stream, flush=True)


def tuning_seeds_error(seeds: list[int], tuning_seeds: list[int]) -> str | None:
    """Why a study may not report ``seeds`` (those among the seeds that chose its settings), or ``None``."""
    chosen = sorted(set(seeds) & set(tuning_seeds))
    return f"--seeds {chosen} also chose the settings (--tuning-seeds); report other seeds" if chosen else None


def cluster_or_exit(address: str) -> str:
    """A many-runs command's ``--address``, checked before anything is written: the address of
    the cluster that answered, or one line and exit 2 where none does (not a hang)."""
    from league.cluster import ClusterError, check_cluster

    try:
        return check_cluster(address, nullcontext)
    except ClusterError as err:
        print(f"error: {err}", file=sys.stderr)
        raise SystemExit(2) from None

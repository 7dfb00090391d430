"""Agent names, their index in every batched array, and the game's outcomes."""

from __future__ import annotations

from enum import IntEnum

ATTACKER, TARGETER, DEFENDER = 0, 1, 2
AGENTS: tuple[str, str, str] = ("attacker", "targeter", "defender")


class Outcome(IntEnum):
    """How a game ended; ``RUNNING`` while it goes on."""

    RUNNING = 0
    CAPTURED = 1  # A came within its capture radius of T: attacker wins
    TIMEOUT = 2  # Gamma steps passed without T at the terminal ("dispels T"): attacker wins
    TERMINAL_REACHED = 3  # T entered the terminal sphere: team wins
    ATTACKER_INTERCEPTED = 4  # D came within its capture radius of A first: team wins

    @property
    def label(self) -> str:
        return self.name.lower()

    @property
    def attacker_wins(self) -> bool:
        return self in (Outcome.CAPTURED, Outcome.TIMEOUT)


# The Outcome values the attacker wins, for arrays of outcomes (``np.isin``).
ATTACKER_WIN_VALUES = tuple(int(o) for o in Outcome if o.attacker_wins)


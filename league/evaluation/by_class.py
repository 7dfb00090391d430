"""Attacker win rates by start class (``envs.start_classes``) and the free losses.

A start is a T-race, A-certain or contested by straight-line geometry before anyone moves;
a single win rate over all starts mixes what the geometry decides with what the players
decide. The *free losses* are what a side gave away that the geometry had given it: a
team's losses on T-race starts, an attacker's failures on A-certain ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envs.config import GameConfig
from envs.scenarios import evaluation_scenarios
from envs.start_classes import StartClass, class_counts, classify, win_rates_by_class

CLASSES = tuple(StartClass)


def game_classes(game: GameConfig, games: str, episodes: int) -> np.ndarray:
    """The start class of each of the first ``episodes`` fixed ``games`` (``dev`` or ``test``) of the game's scenario set."""
    return classify(evaluation_scenarios(game.scenario, episodes, games), game)


def free_losses(side: str, rates: dict[StartClass, float | None]) -> float | None:
    """From the attacker win rate per class: the team's win rate given away on T-race starts
    (``side`` ``team``) or the attacker's on A-certain ones; ``None`` without such starts."""
    if side == "team":
        return rates[StartClass.T_RACE]
    won = rates[StartClass.A_CERTAIN]
    return None if won is None else 1.0 - won


@dataclass(frozen=True)
class ClassRates:
    """One pair's attacker win rate on each start class."""

    rates: dict[StartClass, float | None]

    @classmethod
    def of(cls, attacker_wins: np.ndarray, classes: np.ndarray) -> "ClassRates":
        """From the pair's per-game attacker wins, its first games in the order of ``classes``."""
        return cls(win_rates_by_class(attacker_wins, classes[: len(attacker_wins)]))

    def free_losses(self, side: str) -> float | None:
        return free_losses(side, self.rates)

    def as_json(self) -> dict:
        return {"attacker_win_rate": {c.value: r for c, r in self.rates.items()},
                "free_losses": {side: self.free_losses(side) for side in ("team", "attacker")}}

    def cells(self) -> list[str]:
        """The rate of each class, then the team's and the attacker's free losses ("-": no such start)."""
        values = [*(self.rates[c] for c in CLASSES), self.free_losses("team"), self.free_losses("attacker")]
        return ["-" if v is None else f"{v:.3f}" for v in values]


def class_header(classes: np.ndarray) -> list[str]:
    """Column names of ``ClassRates.cells``, each class with its count of starts."""
    counts = class_counts(classes)
    return [*(f"{c.value} ({counts[c]})" for c in CLASSES), "team's free losses", "attacker's free losses"]


CLASS_NOTE = ("Attacker win rate on each start class (`envs.start_classes`: what straight-line geometry decides "
              "before anyone moves). Free losses: the team's losses on T-race starts, the attacker's failures on "
              "A-certain ones.")


def class_table(rows: list[tuple[str, str, ClassRates]], classes: np.ndarray) -> str:
    """Markdown: ``(attacker, team, rates)`` rows under ``class_header``."""
    header = ["attacker", "team", *class_header(classes)]
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join("---" for _ in header) + " |"]
    lines += [f"| {attacker} | {team} | " + " | ".join(rates.cells()) + " |" for attacker, team, rates in rows]
    return "\n".join(lines) + "\n"

"""What a scripted player reads of a batch of games: ``GameView``, and ``DecodedGames``, the view
of games known only by their global states."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from envs.config import GameConfig


class GameView(Protocol):
    """What a scripted player reads of ``N`` games; ``envs.core.BatchedGame`` is one.

    Read-only members, so that a frozen ``DecodedGames`` is one too.
    """

    @property
    def config(self) -> GameConfig: ...

    @property
    def positions(self) -> np.ndarray: ...  # (N, 3 agents, 3)

    @property
    def headings(self) -> np.ndarray: ...  # (N, 3 agents, 2): yaw, pitch

    @property
    def speeds(self) -> np.ndarray: ...  # (3 agents,)


@dataclass(frozen=True)
class DecodedGames:
    """Games known only by their global states: the ``GameView`` of ``act_from_state``."""

    config: GameConfig
    positions: np.ndarray
    headings: np.ndarray

    @property
    def speeds(self) -> np.ndarray:
        return np.asarray(self.config.speeds)

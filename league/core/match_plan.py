"""Which modules play each episode: ``MatchPlan``, the league's agent-to-module mapping for one phase.

"Match" here is one episode's pairing of modules, decided once per episode from (seed,
episode id). Not to be confused with ``envs.match`` (playing whole games between
controllers) or the store's ``matches`` table (the outcome counts of games played).

The plan is a picklable object sent to every env runner, where RLlib calls it as its
``policy_mapping_fn``; it keeps no state between episodes but the last one's answer
(its three agents ask one after the other), so the same episode gets the same match
whoever asks, whenever.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field
from typing import Any

import numpy as np


def _draw(seed: int, episode_id: str, salt: str, weights: list[float]) -> int:
    """Index drawn with ``weights``, fixed by (seed, episode, salt): no state between calls."""
    if len(weights) == 1:  # the only index, whatever the draw (seeding the generator costs more than the rest)
        return 0
    cumulative = np.cumsum(weights)
    draw = random.Random(f"{seed}:{episode_id}:{salt}").random() * cumulative[-1]
    return int(min(np.searchsorted(cumulative, draw, side="right"), len(weights) - 1))


@dataclass
class MatchPlan:
    """Agent -> module mapping for one phase.

    Each episode draws one of the side's ``learners`` (uniformly; the coordinator lists the
    side's exploiters among them, so each gets a learner's share of the games), then that
    learner's opponent with its ``probabilities`` (PFSP, or uniform over an exploiter's
    targets); both draws depend only on the seed and the episode id, so every agent of an
    episode gets the same match.
    """

    learners: list[dict[str, str]]
    opponents: list[list[dict[str, str]]]
    probabilities: list[list[float]]
    seed: int
    # The last episode's match: its three agents ask one after the other.
    _last: tuple[str, dict[str, str]] = field(default=("", {}), repr=False, compare=False)

    def match(self, episode_id: str) -> dict[str, str]:
        if self._last[0] != episode_id:
            k = _draw(self.seed, episode_id, "learner", [1.0] * len(self.learners))
            opponent = self.opponents[k][_draw(self.seed, episode_id, "opponent", self.probabilities[k])]
            self._last = (episode_id, {**self.learners[k], **opponent})
        return self._last[1]

    def __call__(self, agent_id: str, episode: Any = None, **kwargs: Any) -> str:
        """RLlib's ``policy_mapping_fn``: the module of ``agent_id`` in ``episode``."""
        return self.match(episode.id_)[agent_id]

"""Progress over generations: every snapshot of each side against a fixed panel, the scripted
players of the other side. A learner's snapshots (``attacker-m2-v3``) and an exploiter's
(``team-exploiter-v1``) form separate lineages (``attacker-m2``, ``team-exploiter``).

A league that improves shows each lineage's win rate rising with the snapshot version
against the whole panel; one that cycles shows it rising against some panel members and
falling against others, or going up and down. The numbers are each pair's newest
evaluation on the fixed games (``python -m league.report`` plays a pair the run never
evaluated before it builds the report; a point still missing is named under the plot).
``league.reports.plots`` and ``league.reports.html`` draw the lines.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from league.analysis.statistics import wilson_interval
from league.core.payoff import record_against
from league.core.players import POOL_KINDS, SNAPSHOT_KIND, Player, base_name

SIDES = ("attacker", "team")
TRAINED_KIND = {frozen: trained for trained, frozen in SNAPSHOT_KIND.items()}  # exploiter_snapshot -> exploiter
PANEL_TITLES = {"attacker": "attacker snapshots vs the scripted teams", "team": "team snapshots vs the scripted attackers"}


@dataclass(frozen=True)
class GenerationLine:
    """One lineage's snapshots (``attacker-m2``, ``team-exploiter``) against one scripted opponent, by version."""

    side: str
    lineage: str
    opponent: str
    versions: list[int]
    wins: list[int]  # the snapshot's wins
    games: list[int]
    kind: str  # the snapshots' kind: a learner's (snapshot) or an exploiter's (exploiter_snapshot)

    @property
    def label(self) -> str:
        return f"{self.lineage} vs {self.opponent}"

    @property
    def rates(self) -> list[float]:
        return [w / n for w, n in zip(self.wins, self.games)]

    @property
    def intervals(self) -> list[tuple[float, float]]:
        return [wilson_interval(w, n) for w, n in zip(self.wins, self.games)]

    def error_bars(self) -> tuple[list[float], list[float]]:
        """Distances from each rate down and up to its interval's ends; at 0 or 1 wins of all
        games the interval's end lands on the rate up to rounding (1 - 1e-16), not past it."""
        below = [max(0.0, r - low) for r, (low, _) in zip(self.rates, self.intervals)]
        above = [max(0.0, high - r) for r, (_, high) in zip(self.rates, self.intervals)]
        return below, above


def lineage(snapshot: Player) -> str:
    """The name of the learner or exploiter a snapshot was frozen from (``attacker-m2``, ``team-exploiter``);
    of a pool member trained by none, its kind after its side's name (``attacker-m2-oracle``)."""
    trained = TRAINED_KIND.get(snapshot.kind)
    return replace(snapshot, kind=trained).name if trained else f"{base_name(snapshot)}-{snapshot.kind}"


def generation_lines(
    players: list[Player], payoff: dict[tuple[int, int], tuple[int, int]]
) -> tuple[list[GenerationLine], list[str]]:
    """The lines of both sides from ``{(attacker id, team id): (attacker wins, games)}``, and the missing points."""
    lines, missing = [], []
    for side in SIDES:
        snapshots = [p for p in players if p.side == side and p.kind in POOL_KINDS]
        panel = [p for p in players if p.side != side and p.kind == "scripted"]
        lineages = sorted({(s.kind, lineage(s)) for s in snapshots}, key=lambda k: (POOL_KINDS.index(k[0]), k[1]))
        for kind, name in lineages:  # the learners' lineages first
            members = sorted((s for s in snapshots if lineage(s) == name), key=lambda s: s.version)
            for opponent in panel:
                versions, wins, games = [], [], []
                for snapshot in members:
                    won, n = record_against(payoff, side, snapshot.id, opponent.id)
                    if not n:
                        missing.append(f"{snapshot.name} vs {opponent.name} not evaluated")
                        continue
                    versions.append(snapshot.version)
                    wins.append(won)
                    games.append(n)
                lines.append(GenerationLine(side, name, opponent.name, versions, wins, games, kind))
    return lines, missing

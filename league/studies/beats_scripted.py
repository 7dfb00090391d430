"""Do a config's final players beat the scripted ones? Each seed's run measured on the held-out test games.

For each run (one training seed): every scripted player of ``envs.scripted`` joins its league
(``league.evaluation.panel``), then its final players (the newest snapshot of each attacker
reward method and of the team), their untrained versions 0 and every scripted player play
each other on the fixed *test* games, which no curve, evaluation during training or tuning
played. The results are recorded in the run's store (source ``test``), so a second call
plays only what is missing. Each comparison is a row:

* a final attacker against each scripted team, beside the best scripted attacker against it;
* the final team against each scripted attacker and each final attacker, beside the best
  scripted team against that attacker (the lowest attacker win rate);
* with ``untrained``, the final team beside its version 0 against every attacker, and each
  final attacker beside its version 0 against every team;
* the range of Nash weight the test games' meta-game allows on the trained players of each side.

Each comparison is made twice: on the win rate, and on the player's own reward (an
attacker's return under its reward method, the team's T plus D return, with the game's
terminal reward; the reference's games measured by the same yardstick).

Within one seed a row's verdict compares the two 95% Wilson intervals (better, even, worse);
over seeds, the seed mean gets a Student-t interval and the paired t-test over seeds of
(trained minus reference) decides (``league.analysis.statistics``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from envs.scenarios import evaluation_scenarios
from envs.start_classes import classify, win_rates_by_class
from league.analysis.nash import meta_game, weight_group
from league.analysis.statistics import SEED_INTERVAL, mean_interval, paired_t_test, wilson_interval
from league.core.players import Player
from league.evaluation.by_class import CLASSES, free_losses
from league.evaluation.panel import add_scripted, every_scripted_player
from league.evaluation.learning_curves import GameStats
from league.core.payoff import attacker_won_games
from league.evaluation.results import game_outcomes, test_game_stats
from league.state.run_dir import open_run

SIGNIFICANCE = 0.05  # of the paired t-test over seeds


@dataclass(frozen=True)
class FinalPlayers:
    """The players of one run that a final table compares."""

    attackers: dict[int, Player]  # reward method -> its newest snapshot
    team: Player  # the newest team snapshot
    first_attackers: dict[int, Player]  # reward method -> version 0 (before training)
    first_team: Player
    scripted_attackers: list[Player]
    scripted_teams: list[Player]

    @classmethod
    def of(cls, players: list[Player]) -> "FinalPlayers":
        snapshots = [p for p in players if p.kind == "snapshot"]
        attackers = sorted((p for p in snapshots if p.side == "attacker"), key=lambda p: p.version)
        teams = sorted((p for p in snapshots if p.side == "team"), key=lambda p: p.version)
        if not teams or not attackers:
            raise ValueError("the run has no trained snapshot of each side")
        return cls(
            attackers={p.reward_method: p for p in attackers},
            team=teams[-1],
            first_attackers={p.reward_method: p for p in reversed(attackers)},
            first_team=teams[0],
            scripted_attackers=[p for p in players if p.side == "attacker" and p.kind == "scripted"],
            scripted_teams=[p for p in players if p.side == "team" and p.kind == "scripted"],
        )

    def sides(self, untrained: bool) -> tuple[list[Player], list[Player]]:
        """The attackers and the teams of the table (every pair of them is played)."""
        attackers = [*self.scripted_attackers, *self.attackers.values()]
        teams = [*self.scripted_teams, self.team]
        if untrained:
            attackers += [p for p in self.first_attackers.values() if p not in attackers]
            teams += [self.first_team] if self.first_team not in teams else []
        return attackers, teams


@dataclass(frozen=True)
class Row:
    """One comparison on one seed: ``player`` (its side's view) against ``against``, beside ``reference``."""

    player: str
    against: str
    reference: str
    side: str  # the side ``player`` and ``reference`` play
    attacker_wins: tuple[int, int]  # (wins, games) of the attacker in player's pair
    reference_attacker_wins: tuple[int, int]
    own_return: float  # the player's mean return per game by its own reward
    reference_own_return: float  # the reference's, by the player's reward
    # Per StartClass (envs.start_classes), the attacker win rate in player's pair and in the reference's
    # (None for a class without starts); empty where the games' outcomes were not at hand.
    by_class: tuple[tuple[float | None, float | None], ...] = ()

    @property
    def free_losses(self) -> float | None:
        """What the geometry gave away: a team's losses on T-race starts, an attacker's failures on A-certain ones."""
        if not self.by_class:
            return None
        return free_losses(self.side, {c: mine for c, (mine, _) in zip(CLASSES, self.by_class)})

    @property
    def rate(self) -> float:
        return self.attacker_wins[0] / self.attacker_wins[1]

    @property
    def reference_rate(self) -> float:
        return self.reference_attacker_wins[0] / self.reference_attacker_wins[1]

    @property
    def return_gain(self) -> float:
        return self.own_return - self.reference_own_return

    @property
    def gain(self) -> float:
        """How much better than the reference, for ``side`` (an attacker wins more, a team lets it win less)."""
        return self.rate - self.reference_rate if self.side == "attacker" else self.reference_rate - self.rate

    def verdict(self) -> str:
        """``better``/``worse`` when the two 95% Wilson intervals lie apart, else ``even``."""
        mine, theirs = wilson_interval(*self.attacker_wins), wilson_interval(*self.reference_attacker_wins)
        higher, lower = mine[0] > theirs[1], mine[1] < theirs[0]
        if self.side == "team":
            higher, lower = lower, higher
        return "better" if higher else "worse" if lower else "even"


@dataclass(frozen=True)
class NashRow:
    """The range of Nash weight the meta-game allows on one side's trained players."""

    side: str
    low: float
    high: float


def measure_on_test_games(run_dir: Path, episodes: int, untrained: bool = True, workers: int = 0) -> tuple[list[Row], list[NashRow]]:
    """One run's rows on the first ``episodes`` test games, playing the pairs not yet recorded."""
    run, store = open_run(run_dir)
    try:
        add_scripted(store, every_scripted_player())
        final = FinalPlayers.of(store.players())
        attackers, teams = final.sides(untrained)
        stats = test_game_stats(store, run, run_dir, [(a, t) for a in attackers for t in teams], episodes, workers)
        wins = {pair: attacker_won_games(outcomes) for pair, outcomes in game_outcomes(store, "test").items()}
    finally:
        store.close()
    classes = classify(evaluation_scenarios(run.game.scenario, episodes, "test"), run.game)
    table = {pair: (s.attacker_wins, s.games) for pair, s in stats.items()}
    rows = comparisons(final, stats, untrained, run.game.terminal_reward, (wins, classes))
    return rows, nash_rows(attackers, teams, table)


def comparisons(
    final: FinalPlayers, stats: dict[tuple[int, int], GameStats], untrained: bool, terminal_reward: float,
    games: tuple[dict[tuple[int, int], np.ndarray], np.ndarray] | None = None,
) -> list[Row]:
    """Every row of one run from its test-game results by ``(attacker id, team id)``; with ``games``
    (each pair's per-game attacker wins, each game's start class), the rates by class too."""

    def by_class(pair: tuple[int, int]) -> list[float | None]:
        wins, classes = games
        rates = win_rates_by_class(wins[pair], classes)
        return [rates[c] for c in CLASSES]

    def row(player: Player, against: Player, reference: Player) -> Row:
        pair = (lambda p: (p, against)) if player.side == "attacker" else (lambda p: (against, p))
        mine, theirs = stats[ids(*pair(player))], stats[ids(*pair(reference))]

        def own(s: GameStats) -> float:
            if player.side == "attacker":
                return s.attacker_return(player.reward_method, terminal_reward)
            return s.team_return(terminal_reward)

        classes = tuple(zip(by_class(ids(*pair(player))), by_class(ids(*pair(reference))))) if games else ()
        return Row(player.name, against.name, reference.name, player.side, (mine.attacker_wins, mine.games),
                   (theirs.attacker_wins, theirs.games), own(mine), own(theirs), classes)

    def rate(attacker: Player, team: Player) -> float:
        return stats[ids(attacker, team)].win_rate("attacker")

    rows = []
    for attacker in final.attackers.values():
        for team in final.scripted_teams:
            best = max(final.scripted_attackers, key=lambda a: rate(a, team))
            rows.append(row(attacker, team, best))
    for attacker in [*final.scripted_attackers, *final.attackers.values()]:
        best = min(final.scripted_teams, key=lambda t: rate(attacker, t))
        rows.append(row(final.team, attacker, best))
    if untrained:
        attackers, teams = final.sides(untrained)
        rows += [row(final.team, attacker, final.first_team) for attacker in attackers]
        for method, attacker in final.attackers.items():
            rows += [row(attacker, team, final.first_attackers[method]) for team in teams]
    return rows


def ids(attacker: Player, team: Player) -> tuple[int, int]:
    return attacker.id, team.id


def nash_rows(attackers: list[Player], teams: list[Player], table: dict) -> list[NashRow]:
    """On each side, the least and most Nash weight any equilibrium puts on trained players (version > 0)."""
    meta = meta_game(attackers, teams, table)
    return [NashRow(side, *meta.weight_range(side, [p for p in players if trained(p)]))
            for side, players in (("attacker", attackers), ("team", teams))]


def trained(player: Player) -> bool:
    """A frozen player that training made: not a scripted player nor a learner's untrained version 0."""
    return weight_group(player) != "scripted_and_v0"


def seed_verdict(gains: list[float]) -> tuple[float, str]:
    """The paired t-test's p-value over seeds of the trained player's gains on its reference, and the verdict."""
    p = paired_t_test(gains)
    mean = float(np.mean(gains))
    return p, ("better" if mean > 0 else "worse") if p < SIGNIFICANCE else "even"


def table(per_seed: dict[int, tuple[list[Row], list[NashRow]]]) -> str:
    """Markdown: the win-rate table (a row per comparison, a column per seed, the mean with its
    interval, the test over seeds, then the Nash ranges), and the same comparisons on the own reward."""
    seeds = sorted(per_seed)
    columns = " | ".join(f"seed {s}" for s in seeds)
    rule = " | ".join("---" for _ in seeds)
    rates = [
        f"| trained player | against | {columns} | mean [{SEED_INTERVAL}] | reference | its rate (mean) | paired t-test p | over seeds |",
        f"| --- | --- | {rule} | --- | --- | --- | --- | --- |",
    ]
    returns = [
        f"| trained player | against | {columns} | mean [{SEED_INTERVAL}] | reference | its return (mean) | paired t-test p | over seeds |",
        f"| --- | --- | {rule} | --- | --- | --- | --- | --- |",
    ]
    for index, head in enumerate(per_seed[seeds[0]][0]):
        rows = [per_seed[s][0][index] for s in seeds]
        cells = [f"{r.rate:.3f} [{wilson_interval(*r.attacker_wins)[0]:.3f}, {wilson_interval(*r.attacker_wins)[1]:.3f}] {r.verdict()}"
                 for r in rows]
        rates.append(summary_line(head, cells, [r.rate for r in rows], [r.reference_rate for r in rows],
                                  [r.gain for r in rows], "{:.3f}"))
        returns.append(summary_line(head, [f"{r.own_return:.1f}" for r in rows], [r.own_return for r in rows],
                                    [r.reference_own_return for r in rows], [r.return_gain for r in rows], "{:.1f}"))
    for index, head in enumerate(per_seed[seeds[0]][1]):
        ranges = [per_seed[s][1][index] for s in seeds]
        rates.append(
            f"| trained {head.side}s | Nash weight [least, most] | "
            + " | ".join(f"[{n.low:.3f}, {n.high:.3f}]" for n in ranges)
            + f" | least over seeds {min(n.low for n in ranges):.3f} | | | | |"
        )
    text = ("Attacker win rate, 95% Wilson interval and verdict within each seed's test games:\n\n" + "\n".join(rates)
            + "\n\nThe same comparisons on the player's own reward (mean return per game):\n\n" + "\n".join(returns) + "\n")
    return text + class_table(per_seed)


def class_table(per_seed: dict[int, tuple[list[Row], list[NashRow]]]) -> str:
    """Markdown: the comparisons with a scripted reference by start class, means over seeds, and the free losses."""
    seeds = sorted(per_seed)
    first = per_seed[seeds[0]][0]
    if not first or not first[0].by_class:
        return ""
    lines = [
        "| trained player | against | " + " | ".join(f"{c.value}: it / reference" for c in CLASSES)
        + " | free losses, mean [least, most] over seeds |",
        "| --- | --- | " + " | ".join("---" for _ in CLASSES) + " | --- |",
    ]
    for index, head in enumerate(first):
        if not head.reference.startswith("scripted-"):
            continue
        rows = [per_seed[s][0][index] for s in seeds]
        cells = []
        for k in range(len(CLASSES)):
            mine, theirs = ([r.by_class[k][j] for r in rows] for j in (0, 1))
            cells.append("-" if mine[0] is None else f"{np.mean(mine):.3f} / {np.mean(theirs):.3f}")
        free = [r.free_losses for r in rows]
        lines.append(f"| {head.player} | {head.against} | " + " | ".join(cells) + " | "
                     + ("-" if free[0] is None else f"{np.mean(free):.3f} [{min(free):.3f}, {max(free):.3f}]") + " |")
    return ("\nBy start class (`envs/start_classes.py`: what straight-line geometry decides before anyone moves), "
            "attacker win rates, means over seeds; free losses: a team's losses on T-race starts, an attacker's "
            "failures on A-certain ones:\n\n" + "\n".join(lines) + "\n")


def summary_line(head: Row, cells: list[str], values: list[float], references: list[float], gains: list[float], number: str) -> str:
    """One comparison's row: the per-seed cells, then the mean with its interval, the reference, the test."""
    low, high = mean_interval(values)
    p, verdict = seed_verdict(gains)
    mean = number.format(float(np.mean(values)))
    return (f"| {head.player} | {head.against} | " + " | ".join(cells)
            + f" | {mean} [{number.format(low)}, {number.format(high)}] | {head.reference} | "
            + f"{number.format(float(np.mean(references)))} | {p:.3g} | **{verdict}** |")

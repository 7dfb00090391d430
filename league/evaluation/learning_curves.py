"""Learning curves: the learners measured on the fixed evaluation games while they train.

Each time a learner passes another multiple of ``evaluation.curve_every_env_steps`` of its
own env steps, the coordinator plays it, as it is at that iteration (the learner's
weights, deterministic actions, in the driver), against each of its curve opponents on
the first ``evaluation.curve_episodes`` fixed evaluation games, and stores one point per
(learner, opponent) in ``league.db`` (``curve_points``):

| learner  | curve opponents                                                            |
| -------- | -------------------------------------------------------------------------- |
| attacker | the scripted teams of the config (the paper's team for the paper configs)  |
| team     | the scripted attackers it trains against, and the newest snapshot of each  |
|          | attacker reward method it trains against (the frozen attacker of phase 2)  |

A point holds the games, the attacker's wins, and per game the mean of A's per-step
rewards under **each** of the methods 1, 2, 3 (whatever method the attacker trains on)
and of T's and D's per-step rewards (Eq. 10, 11). The games are played without the
terminal reward, so the stored returns are the paper's rewards; the return with a
terminal reward ``R`` follows from the wins (``GameStats.attacker_return``,
``GameStats.team_return``): each game adds ``+R`` to A's return if A won it, ``-R`` if
not, and the opposite to T's and D's each.

Reference rows (``curve_references``), measured once per run and curve opponent on the
same games: every scripted player of the learner's side (``envs.scripted``: the
attackers ``pure_pursuit``, ``lead_intercept``, ``proportional_navigation``,
``evade_defender``; every scripted team) and the untrained learner (its version-0 snapshot).

The coordinator hands in the live learners' modules (``league.rllib.bridge.live_module``):
measuring needs no RLlib. ``read_curves`` reads the points back; ``league.reports.plots``
draws them, ``league.studies.seed_curves`` compares several runs (``python -m league.curves``).
"""


from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable

from envs.match import GameResults
from envs.scripted import PLAYERS
from league.analysis.statistics import wilson_interval
from league.config import RunConfig
from league.core.payoff import wins_of
from league.core.players import NewPlayer, Player
from league.evaluation.engine import evaluate_pair, load_module

# Where a live learner's module is "loaded" from: it comes from the algorithm, not the disk.
LIVE_MODULES = "live-learners"


# ---------------------------------------------------------------- one measurement
@dataclass(frozen=True)
class GameStats:
    """One player against one opponent on the first ``games`` fixed evaluation games.

    Returns are means per game of per-step rewards, without any terminal reward.
    """

    games: int
    attacker_wins: int
    attacker_return_1: float
    attacker_return_2: float
    attacker_return_3: float
    targeter_return: float
    defender_return: float
    mean_steps: float

    @staticmethod
    def of(result: GameResults) -> "GameStats":
        by_method = result.attacker_returns.mean(axis=0)
        return GameStats(
            games=len(result.outcome),
            attacker_wins=int(result.attacker_wins.sum()),
            attacker_return_1=float(by_method[0]),
            attacker_return_2=float(by_method[1]),
            attacker_return_3=float(by_method[2]),
            targeter_return=float(result.returns[:, 1].mean()),
            defender_return=float(result.returns[:, 2].mean()),
            mean_steps=float(result.steps.mean()),
        )

    @staticmethod
    def from_row(row: dict[str, Any]) -> "GameStats":
        return GameStats(**{name: row[name] for name in GameStats.__dataclass_fields__})

    def columns(self) -> dict[str, float]:
        return dict(self.__dict__)

    def win_rate(self, side: str) -> float:
        return wins_of(side, self.attacker_wins, self.games) / self.games

    def win_interval(self, side: str) -> tuple[float, float]:
        """95% Wilson interval of ``side``'s win rate."""
        return wilson_interval(wins_of(side, self.attacker_wins, self.games), self.games)

    def _mean_bonus(self, terminal_reward: float) -> float:
        """Mean terminal reward of A per game: ``+R`` per win, ``-R`` per loss."""
        return terminal_reward * (2 * self.attacker_wins / self.games - 1)

    def attacker_return(self, method: int, terminal_reward: float = 0.0) -> float:
        """A's mean return per game under reward ``method`` (1, 2, 3), with a terminal reward of ``R``."""
        return getattr(self, f"attacker_return_{method}") + self._mean_bonus(terminal_reward)

    def team_return(self, terminal_reward: float = 0.0) -> float:
        """T's plus D's mean return per game (Eq. 10 + 11), with a terminal reward of ``R`` (``-R`` each per A win)."""
        return self.targeter_return + self.defender_return - 2 * self._mean_bonus(terminal_reward)


# ---------------------------------------------------------------- measuring during training
def curve_opponents(side: str, candidates: list[Player], scripted_teams: list[Player]) -> list[Player]:
    """Who a ``side`` learner is measured against (see the module docstring)."""
    if side == "attacker":
        return list(scripted_teams)
    newest: dict[int | None, Player] = {}
    for player in candidates:  # oldest first: the last snapshot of a method is its newest
        if player.kind == "snapshot":
            newest[player.reward_method] = player
    return [p for p in candidates if p.kind == "scripted"] + list(newest.values())


def scripted_references(side: str) -> list[Player]:
    """Every scripted player of ``side`` as a league player without a row (``NewPlayer.unrecorded``)."""
    if side == "attacker":
        return [NewPlayer("attacker", "scripted", 0, scripted_attacker=name).unrecorded() for name in PLAYERS["attacker"]]
    return [
        NewPlayer("team", "scripted", 0, scripted_targeter=targeter, scripted_defender=defender).unrecorded()
        for targeter in PLAYERS["targeter"]
        for defender in PLAYERS["defender"]
    ]


@dataclass(frozen=True)
class CurvePoint:
    learner: Player
    opponent: Player
    env_steps: int
    stats: GameStats


@dataclass(frozen=True)
class Reference:
    opponent: Player
    side: str
    kind: str  # "scripted" or "untrained"
    name: str
    player: int | None  # the version-0 snapshot's id of an "untrained" row
    stats: GameStats


@dataclass
class Measurements:
    points: list[CurvePoint]
    references: list[Reference]


class LearningCurves:
    """Measures the learners when their curve points are due; the coordinator stores them."""

    def __init__(self, run: RunConfig, run_dir: Path, log: Callable[[str], None] = print):
        self.run, self.run_dir, self.log = run, Path(run_dir), log
        self.every = run.evaluation.curve_every_env_steps
        self.episodes = run.evaluation.curve_episodes
        # The paper's rewards only: the terminal reward is derived on read (GameStats).
        self.game = run.game.model_copy(update={"terminal_reward": 0.0})
        self.frozen_modules: dict[str, Any] = {}  # saved modules of snapshots, loaded once

    def due(self, learners: list[Player], steps_before: dict[str, int], steps_now: dict[str, int]) -> list[Player]:
        """The learners that passed another multiple of ``curve_every_env_steps`` since ``steps_before``."""
        if not self.every:
            return []
        return [
            p for p in learners if steps_now.get(p.name, 0) // self.every > steps_before.get(p.name, 0) // self.every
        ]

    def measure(
        self,
        live_module: Callable[[Player], Any],
        store: Any,
        learners: list[Player],
        candidates: list[Player],
        steps_before: dict[str, int],
        steps_now: dict[str, int],
    ) -> Measurements:
        """Curve points of the due ``learners`` (all of one side), and the reference rows not yet
        stored; ``live_module(learner)`` is the learner's module as it is now, in eval mode."""
        measured = Measurements([], [])
        due = self.due(learners, steps_before, steps_now)
        if not due:
            return measured
        side = due[0].side
        opponents = curve_opponents(side, candidates, store.players(side="team", kind="scripted"))
        stored = {(r["opponent"], r["kind"], r["name"]) for r in store.curve_references()}
        live: dict[str, Any] = {}
        for learner in due:
            path = Path(LIVE_MODULES, learner.name)
            live[str(self.run_dir / path)] = live_module(learner)
            current = replace(learner, checkpoint=str(path))
            untrained = next(
                (p for p in store.players(side=side, kind="snapshot") if p.parent == learner.id and p.version == 0), None
            )
            for opponent in opponents:
                stats = self.play(current, opponent, live)
                measured.points.append(CurvePoint(learner, opponent, steps_now[learner.name], stats))
                self.log(self.describe(learner, opponent, steps_now[learner.name], stats))
                references = [(p, "scripted") for p in scripted_references(side)]
                references += [(untrained, "untrained")] if untrained is not None else []
                for reference, kind in references:
                    key = (opponent.id, kind, reference.name)
                    if key in stored:
                        continue
                    stored.add(key)
                    player = reference.id if kind == "untrained" else None
                    measured.references.append(
                        Reference(opponent, side, kind, reference.name, player, self.play(reference, opponent, live))
                    )
        return measured

    def play(self, player: Player, opponent: Player, live: dict[str, Any]) -> GameStats:
        attacker, team = (player, opponent) if player.side == "attacker" else (opponent, player)
        result = evaluate_pair(self.game, attacker, team, self.episodes, self.run_dir, load=lambda path: self.load(path, live))
        return GameStats.of(result.result)

    def load(self, path: Path, live: dict[str, Any]) -> Any:
        key = str(path)
        if key in live:
            return live[key]
        if key not in self.frozen_modules:
            self.frozen_modules[key] = load_module(path)
        return self.frozen_modules[key]

    def describe(self, learner: Player, opponent: Player, env_steps: int, stats: GameStats) -> str:
        low, high = stats.win_interval(learner.side)
        own = (
            f"method-{learner.reward_method} return {stats.attacker_return(learner.reward_method, self.run.game.terminal_reward):.2f}"
            if learner.side == "attacker"
            else f"team return {stats.team_return(self.run.game.terminal_reward):.2f}"
        )
        return (
            f"curve: {learner.name} at {env_steps:,} env steps of its own vs {opponent.name}: wins {stats.win_rate(learner.side):.3f} "
            f"[{low:.3f}, {high:.3f}] of {stats.games}, {own}"
        )

    @staticmethod
    def record(store: Any, iteration: int, measured: Measurements) -> None:
        """Write the measurements (inside the iteration's transaction)."""
        for point in measured.points:
            store.record_curve_point(iteration, point.learner.id, point.opponent.id, point.env_steps, point.stats.columns())
        for ref in measured.references:
            store.record_curve_reference(iteration, ref.opponent.id, ref.side, ref.kind, ref.name, ref.player, ref.stats.columns())


# ---------------------------------------------------------------- reading
@dataclass
class Curve:
    """One learner's points against one opponent, and the reference rows of that pairing."""

    learner: Player
    opponent: Player
    env_steps: list[int]
    stats: list[GameStats]
    references: list[tuple[str, str, GameStats]]  # (kind, name, stats)
    iterations: list[int] = field(default_factory=list)  # the run's iteration at each point


def read_curves(store: Any) -> list[Curve]:
    """Every (learner, opponent) curve of a run, with its references, in the order of the learners."""
    players = {p.id: p for p in store.players()}
    grouped: dict[tuple[int, int], list[dict]] = defaultdict(list)
    for row in store.curve_points():
        grouped[(row["learner"], row["opponent"])].append(row)
    references = store.curve_references()
    curves = []
    for (learner_id, opponent_id), rows in sorted(grouped.items()):
        learner = players[learner_id]
        refs = [
            (r["kind"], r["name"], GameStats.from_row(r))
            for r in references
            if r["opponent"] == opponent_id and r["side"] == learner.side
            and (r["kind"] == "scripted" or players.get(r["player"], learner).parent == learner_id)
        ]
        curves.append(Curve(
            learner, players[opponent_id], [r["env_steps"] for r in rows], [GameStats.from_row(r) for r in rows], refs,
            [r["iteration"] for r in rows],
        ))
    return curves

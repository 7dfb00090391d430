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
attackers ``pure_pursuit``, ``lead_intercept``, ``proportional_navigation``; the four
scripted teams) and the untrained learner (its version-0 snapshot).

``python -m league.curves --run-dirs A B C --out DIR`` draws the curves of several runs
of one config (seeds): one thin line per run, their mean, and the reference lines.
``league.report`` draws one run's curves (``plot_run``).
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable

import numpy as np

from envs.match import GameResults
from envs.scripted import PLAYERS
from league.config import RunConfig
from league.evaluation.engine import evaluate_pair, load_module
from league.analysis.statistics import wilson_interval
from league.core.payoff import wins_of
from league.core.players import Player

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
    """Every scripted player of ``side`` as a (row-less) league player."""
    if side == "attacker":
        return [Player(id=-1, side="attacker", kind="scripted", version=0, scripted_attacker=name) for name in PLAYERS["attacker"]]
    return [
        Player(id=-1, side="team", kind="scripted", version=0, scripted_targeter=targeter, scripted_defender=defender)
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
        algo: Any,
        store: Any,
        learners: list[Player],
        candidates: list[Player],
        steps_before: dict[str, int],
        steps_now: dict[str, int],
    ) -> Measurements:
        """Curve points of the due ``learners`` (all of one side), and the reference rows not yet stored."""
        from league.rllib import bridge

        measured = Measurements([], [])
        due = self.due(learners, steps_before, steps_now)
        if not due:
            return measured
        side = due[0].side
        opponents = curve_opponents(side, candidates, store.players(side="team", kind="scripted"))
        stored = {(r["opponent"], r["kind"], r["name"]) for r in store.curve_references()}
        live: dict[str, Any] = {}
        for learner in due:
            module = bridge.learner_spec(self.run, learner.side, learner.reward_method).build()
            module.set_state(bridge.learner_weights(algo, learner.name))
            module.eval()
            path = Path(LIVE_MODULES, learner.name)
            live[str(self.run_dir / path)] = module
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
            learner, players[opponent_id], [r["env_steps"] for r in rows], [GameStats.from_row(r) for r in rows], refs
        ))
    return curves


# ---------------------------------------------------------------- plotting
@dataclass(frozen=True)
class Quantity:
    """One panel: a number per measurement, for a learner of ``side``."""

    title: str
    value: Callable[[GameStats, Player, float], float]  # (stats, learner, terminal reward)


WIN_RATE = Quantity("win rate", lambda s, learner, r: s.win_rate(learner.side))
OWN_RETURN = Quantity(
    "return under its own reward method", lambda s, learner, r: s.attacker_return(learner.reward_method, r)
)
TEAM_RETURN = Quantity("team return (T + D, Eq. 10 + 11)", lambda s, learner, r: s.team_return(r))


def quantities(learner: Player) -> list[Quantity]:
    return [WIN_RATE, OWN_RETURN] if learner.side == "attacker" else [WIN_RATE, TEAM_RETURN]


REFERENCE_STYLES = {"scripted": {"ls": "--", "lw": 1.0}, "untrained": {"ls": ":", "lw": 1.4}}
# One colour per reference, the same in every panel; the untrained player is black.
REFERENCE_COLOURS = ["#8c564b", "#9467bd", "#17becf", "#bcbd22", "#e377c2", "#ff7f0e", "#2ca02c"]


def reference_colour(kind: str, name: str) -> str:
    if kind == "untrained":
        return "black"
    names = [p.name for side in ("attacker", "team") for p in scripted_references(side)]
    return REFERENCE_COLOURS[names.index(name) % len(REFERENCE_COLOURS)] if name in names else "grey"


def _reference_lines(ax, references: list[tuple[str, str, float]]) -> None:
    """Horizontal lines labelled at the right edge; labels pushed apart so they stay readable."""
    ordered = sorted(references, key=lambda r: r[2])
    values = [r[2] for r in ordered]
    low, high = ax.get_ylim()
    low, high = min([low, *values]), max([high, *values])
    gap = (high - low) * 0.07
    placed: list[float] = []
    for kind, name, value in ordered:
        colour = reference_colour(kind, name)
        ax.axhline(value, color=colour, **REFERENCE_STYLES[kind])
        y = max(value, placed[-1] + gap) if placed else value
        placed.append(y)
        label = "untrained (v0)" if kind == "untrained" else name.removeprefix("scripted-")
        ax.annotate(f"{label} {value:.3g}", xy=(1.0, y), xycoords=("axes fraction", "data"), xytext=(4, 0),
                    textcoords="offset points", va="center", fontsize=7, color=colour)
    ax.set_ylim(low - gap, max(high, placed[-1] if placed else high) + gap)


def _win_band(ax, x: list[int], stats: list[GameStats], side: str, colour: str) -> None:
    bounds = np.array([s.win_interval(side) for s in stats])
    ax.fill_between(x, bounds[:, 0], bounds[:, 1], color=colour, alpha=0.15, lw=0, label="95% Wilson interval")


def plot_curves(groups: list[list[Curve]], terminal_reward: float, title: str, out: Path) -> None:
    """``curves_figure`` saved to ``out``."""
    import matplotlib.pyplot as plt

    fig = curves_figure(groups, terminal_reward, title)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def curves_figure(groups: list[list[Curve]], terminal_reward: float, title: str):
    """One row per (learner, opponent) group, one panel per quantity.

    A group holds the same curve of several runs (seeds): one thin line each and their
    mean; a group of one run is drawn as one line with its win-rate interval.
    References are drawn at their mean over the runs.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import EngFormatter, MaxNLocator

    rows, row_inches = len(groups), 3.4
    fig, axes = plt.subplots(rows, 2, figsize=(15, row_inches * rows), squeeze=False)
    for row, group in zip(axes, groups):
        learner, opponent = group[0].learner, group[0].opponent
        for ax, quantity in zip(row, quantities(learner)):
            lines = [(c.env_steps, [quantity.value(s, c.learner, terminal_reward) for s in c.stats]) for c in group]
            if len(group) == 1:
                x, y = lines[0]
                if quantity is WIN_RATE:
                    _win_band(ax, x, group[0].stats, learner.side, "#1f77b4")
                ax.plot(x, y, marker="o", ms=3, lw=1.5, color="#1f77b4", label=learner.name)
            else:
                for k, (x, y) in enumerate(lines):
                    ax.plot(x, y, lw=0.8, alpha=0.5, color="#1f77b4", label="each seed" if k == 0 else None)
                mean_x, mean_y = mean_curve(lines)
                ax.plot(mean_x, mean_y, lw=2.0, color="#d62728", label=f"mean of {len(group)} seeds")
            refs: dict[tuple[str, str], list[float]] = defaultdict(list)
            for curve in group:
                for kind, name, stats in curve.references:
                    refs[(kind, "untrained" if kind == "untrained" else name)].append(
                        quantity.value(stats, curve.learner, terminal_reward)
                    )
            _reference_lines(ax, [(kind, name, float(np.mean(v))) for (kind, name), v in sorted(refs.items())])
            ax.set_xlabel(f"env steps of {learner.name}")
            # At most 5 ticks, as "200k" and "1.2M": full env-step counts ran together.
            ax.xaxis.set_major_locator(MaxNLocator(nbins=5))
            ax.xaxis.set_major_formatter(EngFormatter(sep=""))
            ax.set_title(f"{learner.name} vs {opponent.name}: {quantity.title}", fontsize=9)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7, loc="best")
    note = f" (terminal reward {terminal_reward:g} included)" if terminal_reward else ""
    fig.suptitle(title + note, fontsize=10)
    # Room on the right of each panel for the reference labels (tight_layout ignores them).
    height = row_inches * rows
    fig.subplots_adjust(left=0.05, right=0.83, wspace=0.55, hspace=0.55, top=1 - 0.8 / height, bottom=0.5 / height)
    return fig


def mean_curve(lines: list[tuple[list[int], list[float]]]) -> tuple[np.ndarray, np.ndarray]:
    """Mean of several runs' curves, point by point over the points every run has (runs of one
    config measure at the same env steps, up to a batch); x is the mean of their env steps."""
    length = min(len(x) for x, _ in lines)
    x = np.mean([np.asarray(x[:length], dtype=float) for x, _ in lines], axis=0)
    y = np.mean([np.asarray(y[:length], dtype=float) for _, y in lines], axis=0)
    return x, y


def plot_run(store: Any, run: RunConfig, out: Path) -> bool:
    """Draw one run's curves into ``out``; False (and nothing drawn) when it recorded none."""
    curves = read_curves(store)
    if not curves:
        return False
    plot_curves([[c] for c in curves], run.game.terminal_reward, f"learning curves of {run.name}", out)
    return True


# ---------------------------------------------------------------- several runs
def summary_table(groups: list[list[Curve]], run_names: list[str], terminal_reward: float) -> str:
    """Markdown: each group's last point per run, its mean, and the reference values (means over runs)."""
    lines = []
    for group in groups:
        learner, opponent = group[0].learner, group[0].opponent
        lines += [f"### {learner.name} vs {opponent.name}", "",
                  "| run | env steps | win rate | 95% interval | " + " | ".join(q.title for q in quantities(learner)[1:]) + " |",
                  "| --- | --- | --- | --- | " + " | ".join("---" for _ in quantities(learner)[1:]) + " |"]
        for name, curve in zip(run_names, group):
            last = curve.stats[-1]
            low, high = last.win_interval(learner.side)
            others = " | ".join(f"{q.value(last, curve.learner, terminal_reward):.3f}" for q in quantities(learner)[1:])
            lines.append(f"| {name} | {curve.env_steps[-1]:,} | {last.win_rate(learner.side):.3f} | [{low:.3f}, {high:.3f}] | {others} |")
        refs: dict[str, list[GameStats]] = defaultdict(list)
        for curve in group:
            for kind, name, stats in curve.references:
                refs["untrained (version 0)" if kind == "untrained" else name].append(stats)
        for name, stats in sorted(refs.items()):
            values = " | ".join(
                f"{np.mean([q.value(s, learner, terminal_reward) for s in stats]):.3f}" for q in quantities(learner)[1:]
            )
            rate = np.mean([s.win_rate(learner.side) for s in stats])
            lines.append(f"| reference: {name} | | {rate:.3f} | | {values} |")
        lines.append("")
    return "\n".join(lines)


def study(run_dirs: list[Path], out: Path) -> tuple[Path, Path]:
    """Curves of several runs of one config: ``OUT/curves.png`` and ``OUT/curves.md``."""
    from league.state.run_dir import open_run

    per_run: list[dict[tuple[str, str], Curve]] = []
    configs = []
    for run_dir in run_dirs:
        run, store = open_run(run_dir)
        try:
            per_run.append({(c.learner.name, c.opponent.name): c for c in read_curves(store)})
        finally:
            store.close()
        configs.append(run)
    keys = [k for k in per_run[0] if all(k in curves for curves in per_run)]
    if not keys:
        raise ValueError(f"the runs have no learning curve in common ({', '.join(map(str, run_dirs))})")
    terminal = {run.game.terminal_reward for run in configs}
    if len(terminal) > 1:
        raise ValueError(f"the runs use different terminal rewards {sorted(terminal)}: not one config")
    groups = [[curves[k] for curves in per_run] for k in keys]
    out.mkdir(parents=True, exist_ok=True)
    (reward,) = terminal
    names = [Path(d).name for d in run_dirs]
    plot_curves(groups, reward, f"{configs[0].name}: {len(run_dirs)} runs", out / "curves.png")
    text = f"# Learning curves of {len(run_dirs)} runs\n\nRuns: {', '.join(map(str, run_dirs))}. " \
           f"Last point of each run; references are means over the runs.\n\n" + summary_table(groups, names, reward)
    (out / "curves.md").write_text(text)
    return out / "curves.png", out / "curves.md"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m league.curves",
        description="Learning curves of several runs of one config (seeds): one line per run, their mean, "
        "and the scripted and untrained reference lines; writes OUT/curves.png and OUT/curves.md.",
    )
    parser.add_argument("--run-dirs", type=Path, nargs="+", required=True)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    from league.state.run_dir import RunDirError

    try:
        png, md = study(args.run_dirs, args.out)
    except (RunDirError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"curves written to {png} and {md}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

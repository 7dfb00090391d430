"""How long until a config's players are strong? ``python bench/time_to_strength.py --criterion protocol --run-dirs D...``.

Reads finished runs (one per training seed): each learner's learning curve (its win rate
against its curve opponents on the first ``evaluation.curve_episodes`` dev games, every
``evaluation.curve_every_env_steps`` of its env steps) beside the scripted references on the
same games, and the wall time of every training iteration. A side's criterion holds at a
curve point when it holds against every curve opponent there, by 95% Wilson intervals:

* ``protocol`` (the flagship's): the attacker wins more often than lead intercept against
  the paper's team, intervals apart; the team lets every attacker it trains against win less
  often than the best scripted team does, intervals apart (even, where the best scripted
  team loses no game to that attacker: nothing is below it);
* ``league``: each attacker is at least even with the best scripted attacker against every
  scripted team (its interval reaches the best one's); the team as in ``protocol``.

Printed per run: for each learner, the env steps of its own at the first point where its
criterion holds ("never" if none), and the run's time to criterion, the latest of its
learners' (the time the run needed to be strong had it stopped there), in the run's env
steps and in its wall time of training iterations; then the mean and range over the runs.
The wall times are those the runs recorded: compare them only for runs trained on one
machine under the same load. The env steps do not depend on the load: with each config's
env steps per second measured side by side (``bench/train_throughput.py``), they give
times to criterion that can be compared.
"""

from __future__ import annotations

import argparse
import sys
from itertools import accumulate
from pathlib import Path

import numpy as np

from envs.scripted import PAPER_TEAM
from league.analysis.statistics import wilson_interval
from league.evaluation.learning_curves import Curve, GameStats, read_curves
from league.state.run_dir import RunDirError, open_run

PAPER_TEAM_NAME = f"scripted-{PAPER_TEAM['targeter']}+{PAPER_TEAM['defender']}"


def interval(stats: GameStats) -> tuple[float, float]:
    """The attacker's win rate's 95% Wilson interval."""
    return wilson_interval(stats.attacker_wins, stats.games)


def holds(criterion: str, curve: Curve, point: int) -> bool:
    """Whether the learner's criterion holds against this curve's opponent at curve point ``point``."""
    mine = interval(curve.stats[point])
    scripted = [stats for kind, _, stats in curve.references if kind == "scripted"]
    if curve.learner.side == "team":  # below the best scripted team's rate, intervals apart
        best = min(scripted, key=lambda s: s.attacker_wins / s.games)
        if best.attacker_wins == 0:  # no team can be below a scripted team that never loses: even is the best there is
            return mine[0] <= interval(best)[1]
        return mine[1] < interval(best)[0]
    if criterion == "protocol":
        if curve.opponent.name != PAPER_TEAM_NAME:
            return True  # the protocol asks about the paper's team only
        lead = next(stats for kind, name, stats in curve.references if name == "scripted-lead_intercept")
        return mine[0] > interval(lead)[1]
    best = max(scripted, key=lambda s: s.attacker_wins / s.games)
    return mine[1] >= interval(best)[0]


def first_strong(criterion: str, curves: list[Curve]) -> tuple[int, int] | None:
    """A learner's first curve point at which its criterion holds against every opponent: ``(env steps, iteration)``."""
    for point in range(len(curves[0].stats)):
        if all(point < len(c.stats) and holds(criterion, c, point) for c in curves):
            return curves[0].env_steps[point], curves[0].iterations[point]
    return None


def measure(run_dir: Path, criterion: str) -> tuple[dict[str, tuple[int, int, float] | None], float]:
    """Per learner, at its first strong point: (its own env steps, the run's env steps, the run's
    training seconds); and the run's training seconds."""
    _, store = open_run(run_dir)
    try:
        curves, iterations = read_curves(store), store.iteration_rows()
        learners = [p.name for p in store.players(kind="learner")]
    finally:
        store.close()
    elapsed = dict(zip([row["iteration"] for row in iterations], accumulate(row["wall_seconds"] for row in iterations)))
    run_steps = {row["iteration"]: row["env_steps"] for row in iterations}
    # a learner not yet measured (a run stopped before its first phase) is not strong
    by_learner: dict[str, list[Curve]] = {name: [] for name in learners}
    for curve in curves:
        by_learner.setdefault(curve.learner.name, []).append(curve)
    found = {}
    for name, learner_curves in by_learner.items():
        strong = first_strong(criterion, learner_curves) if learner_curves else None
        found[name] = None if strong is None else (strong[0], run_steps[strong[1]], elapsed[strong[1]])
    return found, elapsed[max(elapsed)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run-dirs", type=Path, nargs="+", required=True, help="finished runs of one config, one per seed")
    parser.add_argument("--criterion", choices=("protocol", "league"), required=True)
    args = parser.parse_args(argv)
    try:
        measured = [(run_dir, *measure(run_dir, args.criterion)) for run_dir in args.run_dirs]
    except RunDirError as err:
        print(f"error: --run-dirs: {err}", file=sys.stderr)
        return 2
    times, steps = [], []
    for run_dir, found, total in measured:
        cells = [f"{name} {'never' if at is None else f'at {at[0]:,} env steps of its own'}" for name, at in found.items()]
        last = None if any(at is None for at in found.values()) else max(found.values(), key=lambda at: at[2])
        times.append(None if last is None else last[2])
        steps.append(None if last is None else last[1])
        print(f"{run_dir}: {'; '.join(cells)}; strong after "
              + ("never" if last is None else f"{last[1]:,} env steps of the run, {last[2]:.0f} s")
              + f" of {total:.0f} s of training iterations")
    reached = [(t, n) for t, n in zip(times, steps) if t is not None]
    if reached:
        seconds, env_steps = [t for t, _ in reached], [n for _, n in reached]
        print(f"time to criterion: mean {np.mean(seconds):.0f} s, range [{min(seconds):.0f}, {max(seconds):.0f}] s; "
              f"mean {np.mean(env_steps):,.0f} env steps, range [{min(env_steps):,}, {max(env_steps):,}]; "
              f"over {len(reached)} of {len(times)} runs")
    else:
        print(f"time to criterion: never reached in {len(times)} runs")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Evaluate a league: ``python -m league.evaluate --run-dir DIR [--games test] [--episodes N] [--players ...] [--add-scripted ...]``.

Plays every chosen attacker against every chosen team on the fixed evaluation games, the
dev games or (``--games test``) the held-out test games that no curve or tuning plays
(frozen players only: snapshots, exploiter snapshots and scripted players), prints win
rates with 95% Wilson intervals and outcome counts, the table per attacker reward method, then the Nash
equilibrium of the meta-game on these results (``league.analysis.nash``). Results go to
the league database as evaluation results of the run's last iteration, replacing earlier
evaluations of the same pairs on the same games (the same fixed games again are one
measurement, not new evidence); dev-game results also refit that iteration's ratings.

``--add-scripted`` first makes scripted players the run's config did not list members of the
league (an attacker by name, ``evade_defender``; a team as ``targeter+defender``), so an old
league can be measured against a new reference player: they join its meta-game, its
reports, and the pool of a resumed run, as if the config had listed them.

``--players`` may name mixture players (``nash-attacker``, ``nash-team``, either ``@ITERATION``;
``league.core.mixture``): each game is played by the member drawn for it from ``--mixture-seed``
and the game's index. A mixture's games are printed (win rates, Wilson intervals, the games
each member played) but not recorded: a mixture is no league member.
"""

from __future__ import annotations

import json
import logging
import sys
from typing import Any
from pathlib import Path

import numpy as np
import torch

from envs.start_classes import class_counts
from league.evaluation.by_class import CLASS_NOTE, ClassRates, class_table, game_classes
from league.evaluation.engine import MissingModuleError, PairEvaluation, Workers, evaluate_pairs
from league.evaluation.panel import add_scripted
from league.evaluation.results import last_iteration, record_evaluations
from league.evaluation.tables import format_table, method_rows, method_table
from league.analysis.nash import format_meta_game, meta_game, meta_game_players
from league.analysis.mixtures import find_mixture
from league.analysis.statistics import wilson_interval
from league.cli import MIXTURE_SEED_HELP, PairProgress, command_parser, count, mixture_seed
from league.core.mixture import Contestant, Mixture, MixtureError
from league.core.players import Player
from league.state.run_dir import RunDirError, open_run


def evaluation_json(scenario: str, games: str, episodes: int, results: list[PairEvaluation], meta: Any,
                    classes: np.ndarray) -> dict:
    """The tables' numbers as data (``--json``; the schema is in docs/evaluation.md)."""
    pairs = []
    for r in results:
        low, high = wilson_interval(r.attacker_wins, r.games)
        pairs.append({
            "attacker": r.attacker.name, "team": r.team.name, "games": r.games, "attacker_wins": r.attacker_wins,
            "attacker_win_rate": r.attacker_wins / r.games, "interval_95": [low, high],
            "outcomes": dict(r.result.outcome_counts()),
            "by_start_class": ClassRates.of(r.result.attacker_wins, classes).as_json(),
        })
    return {
        "scenario": scenario, "games": games, "episodes": episodes,
        "start_classes": {c.value: n for c, n in class_counts(classes).items()},
        "pairs": pairs, "methods": method_rows(league_results(results)), "meta_game": meta.as_json() if meta else None,
        "mixtures": mixture_json(results),
    }


def league_results(results: list[PairEvaluation]) -> list[PairEvaluation]:
    """The pairs of league members (recorded, in the meta-game and the table per reward method)."""
    return [r for r in results if not r.has_mixture]


def mixtures_of(results: list[PairEvaluation]) -> list[Mixture]:
    found = {side.name: side for r in results for side in (r.attacker, r.team) if isinstance(side, Mixture)}
    return list(found.values())


def member_games(results: list[PairEvaluation], mixture: Mixture) -> list[int]:
    """How many of the evaluated games each member of ``mixture`` played, over its pairs."""
    drawn = [name for r in results for side in (r.attacker, r.team) if side == mixture for name in r.members[side.side]]
    return [drawn.count(p.name) for p in mixture.members]


def mixture_json(results: list[PairEvaluation]) -> list[dict]:
    return [{**m.as_json(), "member_games": dict(zip([p.name for p in m.members], member_games(results, m)))}
            for m in mixtures_of(results)]


def mixture_table(results: list[PairEvaluation], seed: int) -> str:
    """Each mixture's members: weight, range over optimal mixtures, and the games each played here."""
    lines = []
    for m in mixtures_of(results):
        lines += [f"{m.line()}; members drawn with --mixture-seed {seed}", "",
                  "| member | weight | range over optimal mixtures | games played |", "| --- | --- | --- | --- |"]
        lines += [f"| {p.name} | {w:.3f} | {low:.3f} to {high:.3f} | {n} |"
                  for p, w, (low, high), n in zip(m.members, m.weights, m.ranges, member_games(results, m))]
        lines.append("")
    return "\n".join(lines)


def choose(players: list[Player], names: list[str] | None, store=None, mixture_seed: int = 0) -> list[Contestant]:
    """The frozen players named (every one without ``names``), mixture players among them (from ``store``,
    drawing from ``mixture_seed``)."""
    frozen = [p for p in players if not p.trains]
    if not names:
        return frozen
    by_name: dict[str, Contestant] = {p.name: p for p in frozen}
    for name in names:
        mixture = find_mixture(store, name, seed=mixture_seed) if store is not None else None
        if mixture is not None:
            by_name[name] = mixture
    unknown = [n for n in names if n not in by_name]
    if unknown:
        raise ValueError(f"unknown or unfrozen players {unknown}; frozen players: {sorted(p.name for p in frozen)}, "
                         "or the mixtures nash-attacker, nash-team")
    return [by_name[n] for n in names]


def main(argv: list[str] | None = None) -> int:
    parser = command_parser(prog="python -m league.evaluate", description=__doc__.splitlines()[0])
    parser.add_argument("--run-dir", type=Path, required=True)
    parser.add_argument("--games", choices=("dev", "test"), default="dev",
                        help="the dev games (curves, training, tuning) or the held-out test games (default: dev)")
    parser.add_argument("--episodes", type=count(1), help="fixed games per pair (default: the run's evaluation.episodes)")
    parser.add_argument("--players", nargs="+",
                        help="player names, or mixtures nash-attacker, nash-team[@ITERATION] (default: every snapshot and scripted player)")
    parser.add_argument("--mixture-seed", type=mixture_seed, default=0, help=MIXTURE_SEED_HELP)
    parser.add_argument(
        "--workers", type=count(0), help="evaluation actors, 0: in this process (default: the run's evaluation.workers)"
    )
    parser.add_argument("--add-scripted", nargs="+", default=[], metavar="NAME",
                        help="scripted players to make league members first: an attacker, or a team as targeter+defender")
    parser.add_argument("--json", action="store_true", help="print the same numbers as one JSON object")
    args = parser.parse_args(argv)
    try:
        run, store = open_run(args.run_dir)
        try:
            added = add_scripted(store, args.add_scripted)
        except ValueError as err:
            raise ValueError(f"--add-scripted {err}") from None
        names = args.players and list(dict.fromkeys([*args.players, *added]))
        players = choose(store.players(), names, store, args.mixture_seed)
    except (RunDirError, MixtureError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    torch.set_num_threads(run.resources.threads_for(1))  # games played here run torch in this process
    episodes = run.evaluation.episodes if args.episodes is None else args.episodes
    workers = run.evaluation.workers if args.workers is None else args.workers
    pairs = [(a, t) for a in players if a.side == "attacker" for t in players if t.side == "team"]
    if not pairs:
        print("error: choose at least one attacker and one team", file=sys.stderr)
        return 2
    started_ray = False
    if workers > 0:
        import ray

        if not ray.is_initialized():
            ray.init(  # a private instance, like league.run's
                address="local", num_cpus=max(1, int(workers * run.evaluation.cpus_per_worker + 0.999)),
                include_dashboard=False, logging_level=logging.ERROR, log_to_driver=False,  # no banners
            )
            started_ray = True
    try:
        ev = run.evaluation
        results = evaluate_pairs(
            run.game, args.run_dir.resolve(), pairs, episodes,
            Workers(workers, ev.cpus_per_worker, ev.custom_resources_per_worker, run.resources.torch_threads),
            games=args.games, progress=PairProgress(f"evaluating on {episodes} {args.games} games each"),
        )
    except MissingModuleError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    finally:
        if started_ray:
            import ray

            ray.shutdown()
    recorded = league_results(results)
    with store.transaction():
        record_evaluations(store, last_iteration(store), recorded, args.games)
    attackers, teams = meta_game_players([p for p in players if isinstance(p, Player)])
    meta = meta_game(attackers, teams, {(r.attacker.id, r.team.id): (r.attacker_wins, r.games) for r in recorded})
    classes = game_classes(run.game, args.games, episodes)
    if args.json:
        print(json.dumps(evaluation_json(run.game.scenario, args.games, episodes, results, meta, classes), indent=1))
        return 0
    print(f"{episodes} fixed {args.games} games of scenario set `{run.game.scenario}` per pair\n")
    print(format_table(results))
    print(CLASS_NOTE + "\n\n" + class_table(
        [(r.attacker.name, r.team.name, ClassRates.of(r.result.attacker_wins, classes)) for r in results], classes))
    if mixtures_of(results):
        print(mixture_table(results, args.mixture_seed))
    print(method_table(recorded))
    print("## Meta-game of the evaluated players\n\n" + format_meta_game(meta, "no snapshot or scripted player on a side"))
    return 0


if __name__ == "__main__":
    sys.exit(main())

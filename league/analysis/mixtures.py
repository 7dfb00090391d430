"""The league's mixture players (``league.core.mixture``) made from its meta-game (``league.analysis.nash``).

``nash-team`` is the team side's Nash mixture of the meta-game ``league.status`` shows: every
frozen player (snapshots, exploiter snapshots, scripted players), each pair on its newest
evaluation on the dev games. ``nash-team@K`` is the same for the frozen players the league had
after iteration ``K`` (created at or before it): a frozen pair's fixed games do not change with
time, so its newest evaluation is the one iteration ``K`` would have measured too. The mixture
is the LP's vertex; each member's range comes from ``weight_range`` (two LPs per member).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from league.analysis.nash import SUPPORT_THRESHOLD, league_meta_game
from league.core.mixture import Mixture, MixtureError, is_mixture_name, parse_mixture_name
from league.core.payoff import OutcomeCount
from league.core.players import Player, Side


def league_mixture(name: str, players: list[Player], evaluation_rows: list[OutcomeCount], last_iteration: int) -> Mixture:
    """The mixture player ``name`` (``nash-attacker``, ``nash-team@120``); ``MixtureError`` naming what is wrong."""
    spec = parse_mixture_name(name)
    iteration = last_iteration if spec.iteration is None else spec.iteration
    if iteration > last_iteration:
        raise MixtureError(f"{name}: the run has no iteration {iteration} (its iterations: 0 to {last_iteration})")
    then = [p for p in players if p.created_iteration <= iteration]
    meta, why_not = league_meta_game(then, evaluation_rows)
    if meta is None:
        raise MixtureError(f"{name}: iteration {iteration} has no meta-game: {why_not}")
    side_players, weights = ((meta.attackers, meta.equilibrium.row_mixture) if spec.side == "attacker"
                             else (meta.teams, meta.equilibrium.column_mixture))
    chosen = sorted(((p, float(w)) for p, w in zip(side_players, weights) if w > SUPPORT_THRESHOLD),
                    key=lambda pw: -pw[1])  # heaviest first; sorted() is stable, so equals keep the meta-game's order
    total = sum(w for _, w in chosen)
    value = meta.equilibrium.value if spec.side == "attacker" else 1.0 - meta.equilibrium.value
    return Mixture(
        name=spec.name, side=spec.side, iteration=iteration, members=tuple(p for p, _ in chosen),
        weights=tuple(w / total for _, w in chosen), ranges=tuple(meta.weight_range(spec.side, [p]) for p, _ in chosen),
        value=value,
    )


def regret_matching_mixture(side: Side, players: list[Player], evaluation_rows: list[OutcomeCount], iteration: int) -> Mixture:
    """``side``'s regret-matching distribution (``league.analysis.regret_matching``) in iteration ``iteration``'s
    meta-game as a mixture player, ``rm-SIDE@K``: its weights' range is the weight (it is no LP's vertex), its
    value its expected win rate against the other side's Nash mixture."""
    from league.analysis.regret_matching import restricted_distributions

    name = f"rm-{side}@{iteration}"
    meta, why_not = league_meta_game([p for p in players if p.created_iteration <= iteration], evaluation_rows)
    if meta is None:
        raise MixtureError(f"{name}: iteration {iteration} has no meta-game: {why_not}")
    by_id = restricted_distributions(meta)
    side_players = meta.attackers if side == "attacker" else meta.teams
    chosen = sorted(((p, by_id[p.id]) for p in side_players if by_id[p.id] > 0), key=lambda pw: -pw[1])
    weights = np.array([by_id[p.id] for p in side_players])
    eq = meta.equilibrium
    value = float(weights @ eq.row_ratings) if side == "attacker" else float(weights @ eq.column_ratings)
    return Mixture(name=name, side=side, iteration=iteration, members=tuple(p for p, _ in chosen),
                   weights=tuple(w for _, w in chosen), ranges=tuple((w, w) for _, w in chosen), value=value)


def store_mixture(store: Any, name: str) -> Mixture:
    """``league_mixture`` on a run's league database (a ``LeagueStore``)."""
    last = store.last_iteration()
    return league_mixture(name, store.players(), store.newest_evaluation_rows(), last["iteration"] if last else 0)


def final_mixtures(store: Any) -> list[Mixture]:
    """``nash-attacker`` and ``nash-team`` of the final meta-game, or none where there is no meta-game."""
    try:
        return [store_mixture(store, name) for name in ("nash-attacker", "nash-team")]
    except MixtureError:
        return []


def find_mixture(store: Any, name: str, side: str | None = None, seed: int = 0) -> Mixture | None:
    """The mixture player ``name`` (of ``side``, if given) when ``name`` asks for one, else ``None`` (a player's
    name, for the caller to look up); ``MixtureError`` for a misspelt mixture, or one of the other side."""
    if not is_mixture_name(name):
        return None
    mixture = replace(store_mixture(store, name), seed=seed)
    if side is not None and mixture.side != side:
        raise MixtureError(f"{name} is a mixture of {mixture.side}s, not of {side}s")
    return mixture

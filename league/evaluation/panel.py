"""The scripted panel: every scripted player of ``envs.scripted`` as a member of a league.

A run's config lists the scripted players it trains against; a final table measures its
players against every scripted player of the other side, so the ones the config did not
list are added first (they join the run's meta-game, its reports, and the pool of a
resumed run, as if the config had listed them).
"""

from __future__ import annotations

from envs.scripted import PLAYERS, ScriptedPlayer
from league.core.players import NewPlayer
from league.evaluation.results import last_iteration
from league.state.store import LeagueStore


def every_scripted_player() -> list[str]:
    """The names of every scripted attacker, then of every scripted team (``targeter+defender``)."""
    return [*sorted(PLAYERS["attacker"]),
            *(f"{t}+{d}" for t in sorted(PLAYERS["targeter"]) for d in sorted(PLAYERS["defender"]))]


def scripted_member(name: str) -> NewPlayer:
    """The league member of a scripted player named ``attacker`` or ``targeter+defender``."""
    targeter, team, defender = name.partition("+")
    try:  # ScriptedPlayer names the unknown player and the known ones
        if team:
            ScriptedPlayer("targeter", targeter), ScriptedPlayer("defender", defender)
        else:
            ScriptedPlayer("attacker", name)
    except ValueError as err:
        raise ValueError(f"{name}: {err} (a team: targeter+defender)") from None
    if team:
        return NewPlayer("team", "scripted", 0, scripted_targeter=targeter, scripted_defender=defender)
    return NewPlayer("attacker", "scripted", 0, scripted_attacker=name)


def add_scripted(store: LeagueStore, names: list[str]) -> list[str]:
    """Make the named scripted players league members (those not yet in it); their names.
    Every name is checked before anything is written."""
    added = [scripted_member(name) for name in names]
    members = {p.name for p in store.players()}
    with store.transaction():
        for player in added:
            if player.name not in members:
                store.add_player(last_iteration(store), player)
                members.add(player.name)
    return [p.name for p in added]

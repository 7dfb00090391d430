"""Where a run stands and its league table, read from the league database only (``python -m league.status``)."""

from __future__ import annotations

from pathlib import Path

from rich.table import Table

from league.analysis.exploitability import EXPLOITABILITY_HEADER, EXPLOITABILITY_NOTE, run_exploitability
from league.analysis.nash import (
    GROUP_HEADER, GROUP_NOTE, GROUP_TITLE, META_GAME_NOTE, MIXTURE_HEADER, MIXTURE_TITLE, league_meta_game,
)
from league.analysis.mixtures import final_mixtures
from league.core.mixture import MIXTURE_MEMBER_HEADER, MIXTURE_MEMBER_NOTE
from league.core.payoff import aggregate, player_record
from league.state.run_dir import FINISHED, STOPPED, usable_checkpoints
from league.state.store import LeagueStore


def league_table(store: LeagueStore, source: str | None = None) -> Table:
    """Players with rating, games and win rate over their games of ``source``, each game counted once;
    no rating for a player without games of ``source`` (nothing it rests on there)."""
    ratings = store.latest_ratings()
    payoff = aggregate(store.counted_results(source))
    table = Table(title="league", caption=f"rating: none for a player without games{' of ' + source if source else ''}")
    for column in ("player", "side", "kind", "reward", "parent", "env steps", "rating", "games", "win rate"):
        table.add_column(column, justify="right" if column in ("env steps", "rating", "games", "win rate") else "left")
    players = store.players()
    names = {p.id: p.name for p in players}
    for player in sorted(players, key=lambda p: -ratings.get(p.id, 0.0)):
        wins, games = player_record(payoff, player.side, player.id)
        table.add_row(
            player.name,
            player.side,
            player.kind,
            str(player.reward_method or ""),
            names.get(player.parent, ""),
            str(player.env_steps),
            f"{ratings[player.id]:.0f}" if player.id in ratings and games else "",
            str(games),
            f"{wins / games:.3f}" if games else "",
        )
    return table


def nash_section(store: LeagueStore) -> list:
    """The meta-game's value, each group's Nash weight and range, the players with nonzero Nash weight
    at the LP's vertex, and the mixture players with each member's weight and range (or why there is no meta-game)."""
    meta, why_not = league_meta_game(store.players(), store.newest_evaluation_rows())
    if meta is None:
        return [f"no meta-game: {why_not}"]
    tables = []
    mixture_rows = [row for mixture in final_mixtures(store) for row in mixture.rows()]
    for title, caption, header, rows in ((GROUP_TITLE, GROUP_NOTE, GROUP_HEADER, meta.group_rows()),
                                         (MIXTURE_TITLE, META_GAME_NOTE, MIXTURE_HEADER, meta.mixture_rows()),
                                         ("mixture players", MIXTURE_MEMBER_NOTE, MIXTURE_MEMBER_HEADER, mixture_rows)):
        table = Table(title=title, caption=caption)
        for column in header:
            table.add_column(column, justify="left" if column in ("side", "group", "player", "mixture", "member") else "right")
        for row in rows:
            table.add_row(*row)
        tables.append(table)
    return [meta.value_line(), *tables]


def exploitability_section(store: LeagueStore) -> list:
    """Each exploited player's best responses (``league.exploit``): their win rates, mean and interval over seeds."""
    found = run_exploitability(store)
    if not found:
        return []
    table = Table(title="exploitability (best responses)", caption=EXPLOITABILITY_NOTE)
    for column in EXPLOITABILITY_HEADER:
        table.add_column(column, justify="left" if column == "player" else "right")
    for item in found:
        table.add_row(*item.row())
    return [table]


def status_json(run_dir: Path, store: LeagueStore, state: str, source: str | None = None) -> dict:
    """What the tables say, as data (``--json``; the schema is in docs/training.md, "Status");
    ``state`` is ``run_dir.run_state``'s."""
    last = store.last_iteration()
    seconds = store.training_seconds()
    usable, problems = usable_checkpoints(run_dir, store)
    ratings = store.latest_ratings()
    payoff = aggregate(store.counted_results(source))
    players = store.players()
    names = {p.id: p.name for p in players}
    rows = []
    for player in players:
        wins, games = player_record(payoff, player.side, player.id)
        rows.append({
            "player": player.name, "side": player.side, "kind": player.kind, "reward_method": player.reward_method,
            "parent": names.get(player.parent), "env_steps": player.env_steps, "rating": ratings.get(player.id) if games else None,
            "games": games, "wins": wins, "win_rate": wins / games if games else None,
        })
    meta, why_not = league_meta_game(players, store.newest_evaluation_rows())
    return {
        "state": state,
        "finished": state == FINISHED,
        "training_done": training_done(store),
        "next": next_step(run_dir, state, usable),
        "iteration": last["iteration"] if last else 0,
        "phase": last["phase"] + 1 if last else None,
        "learner_side": last["learner_side"] if last else None,
        "env_steps": last["env_steps"] if last else 0,
        "episodes": last["episodes"] if last else 0,
        "training_seconds": seconds,
        "env_steps_per_second": last["env_steps"] / seconds if last and seconds > 0 else None,
        "last_checkpoint": {"iteration": usable[0][0], "path": usable[0][1]} if usable else None,
        "warnings": problems,
        "players": rows,
        "meta_game": meta.as_json() if meta is not None else None,
        "mixtures": [mixture.as_json() for mixture in final_mixtures(store)],  # nash-attacker, nash-team
        "no_meta_game": why_not if meta is None else None,  # why ``meta_game`` is null
        "exploitability": [item.as_json() for item in run_exploitability(store)],  # league.exploit's best responses
    }


def training_done(store: LeagueStore) -> bool:
    """Whether the run trained its last iteration (its final evaluation may still be to come)."""
    checkpoint = store.last_checkpoint()
    return bool(checkpoint and checkpoint[2].get("training_done", False))


def next_step(run_dir: Path, state: str, usable: list) -> str | None:
    """What to do with a stopped run (``None`` for one training or finished)."""
    if state != STOPPED:
        return None
    if not usable:
        return f"nothing to resume (no intact checkpoint): delete it (rm -r {run_dir}) and start the run again"
    return f"resume with `python -m league.run --resume {run_dir}`"


def run_line(store: LeagueStore, state: str) -> str:
    """Where the run stands: training (a live process holds its lock), stopped (none does, and its
    final evaluation is not written) or finished; at which phase, and its average speed so far."""
    last = store.last_iteration()
    if not last:
        return f"{state}: no iteration finished yet"
    if state == FINISHED:
        where = "finished"
    elif training_done(store):
        where = f"{state} in its final evaluation (training done)"
    else:
        where = f"{state} in phase {last['phase'] + 1} ({last['learner_side']} learning)"
    seconds = store.training_seconds()
    speed = f"{last['env_steps'] / seconds:.0f} env steps/s on average" if seconds > 0 else "no timing"
    return (
        f"{where}: iteration {last['iteration']}, {last['env_steps']} env steps, {last['episodes']} episodes, "
        f"{seconds:.0f} s of training iterations, {speed}"
    )

"""Replay one fixed evaluation game of two league members:
``python -m league.replay --run-dir DIR --attacker NAME --team NAME [--game K] [--out PATH]``.

Plays game ``K`` of the run's fixed evaluation games (the ones every evaluation plays, with
deterministic actions; ``K`` from 0 to the run's ``evaluation.episodes`` - 1, others are refused)
between any attacker and any team of the league, scripted or trained,
and writes it as an interactive 3D page (the report's trajectory scene: rotate, zoom, step
through) and as a PNG beside it (``envs.render``). By default both go into the run directory,
named after the pair: ``replay-ATTACKER-vs-TEAM-gameK.html`` and ``.png``.

A side may be a mixture player (``nash-attacker``, ``nash-team``, ``@ITERATION``): game ``K`` is
played by the member drawn for it from ``--mixture-seed`` (the one ``league.evaluate`` with that
seed plays on game ``K``), and the page and the printed line name it.
"""

from __future__ import annotations

import html
import sys
from pathlib import Path

from league.analysis.mixtures import find_mixture
from league.cli import MIXTURE_SEED_HELP, command_parser, count, mixture_seed
from league.core.mixture import Mixture, MixtureError
from league.core.players import Player
from league.state.run_dir import RunDirError, open_run


def find_player(players: list[Player], name: str, side: str) -> Player:
    """The league member ``name`` of ``side`` with something to play: scripted, or a saved module."""
    playable = {p.name: p for p in players if p.side == side and (p.kind == "scripted" or p.checkpoint)}
    if name not in playable:
        raise ValueError(f"no {side} {name!r} with a saved policy in the league; {side}s: {', '.join(playable)}")
    return playable[name]


def check_game(game: int, episodes: int) -> None:
    """Refuse a game the run's evaluation does not play (its first ``episodes`` fixed games)."""
    if game >= episodes:
        raise ValueError(
            f"--game {game} is not one of the run's {episodes} fixed evaluation games: "
            f"give 0 to {episodes - 1} (evaluation.episodes)"
        )


def main(argv: list[str] | None = None) -> int:
    parser = command_parser(prog="python -m league.replay", description=__doc__.splitlines()[0])
    parser.add_argument("--run-dir", type=Path, required=True)
    parser.add_argument("--attacker", required=True, help="an attacker of the league (league.status lists them)")
    parser.add_argument("--team", required=True, help="a team of the league")
    parser.add_argument("--game", type=count(0), default=0, help="which fixed evaluation game, 0 to the run's evaluation.episodes - 1 (default 0)")
    parser.add_argument("--out", type=Path, help="the HTML page to write (the PNG goes beside it, .png)")
    parser.add_argument("--mixture-seed", type=mixture_seed, default=0, help=MIXTURE_SEED_HELP)
    args = parser.parse_args(argv)
    try:
        run, store = open_run(args.run_dir)
        try:
            players = store.players()
            mixtures = {side: find_mixture(store, name, side) for side, name in (("attacker", args.attacker), ("team", args.team))}
        finally:
            store.close()
        check_game(args.game, run.evaluation.episodes)
        attacker = find_player(players, args.attacker, "attacker") if mixtures["attacker"] is None else None
        team = find_player(players, args.team, "team") if mixtures["team"] is None else None
    except (RunDirError, MixtureError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    drawn = []  # "MIXTURE drew MEMBER (weight W)" of each mixture side
    for side, mixture in mixtures.items():
        if mixture is not None:
            member = mixture.member_of(args.mixture_seed, args.game)
            drawn.append(f"{mixture.name} drew {member.name} (weight {mixture.weights[mixture.members.index(member)]:.3f}, "
                         f"--mixture-seed {args.mixture_seed})")
            attacker, team = (member, team) if side == "attacker" else (attacker, member)
    assert attacker is not None and team is not None
    names = [m.name if m is not None else p.name for m, p in ((mixtures["attacker"], attacker), (mixtures["team"], team))]
    out = args.out or args.run_dir / f"replay-{names[0]}-vs-{names[1]}-game{args.game}.html"
    if out.is_dir():
        print(f"error: --out {out} is a directory; give a file name, e.g. {out / 'replay.html'}", file=sys.stderr)
        return 2

    import torch

    from envs.render import plot_episode
    from league.evaluation.engine import MissingModuleError
    from league.evaluation.trajectories import replay_game
    from league.reports import html as report_html

    torch.set_num_threads(run.resources.threads_for(1))
    try:
        episode, steps = replay_game(run, args.run_dir, attacker, team, args.game)
    except MissingModuleError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    outcome, pairing = episode.outcome, episode.pairing
    out.parent.mkdir(parents=True, exist_ok=True)
    report_html.write_page(f"Replay: {pairing}", [
        f"<h1>{html.escape(pairing)}</h1>",
        f"<p>{html.escape(outcome.label)} after {steps} steps; fixed evaluation game {args.game} of scenario set "
        f"<code>{html.escape(run.game.scenario)}</code>, deterministic actions.</p>",
        *(f"<p>{html.escape(line)}</p>" for line in drawn),
        report_html.figure_div(report_html.trajectory_figure(episode, run.game), "replay"),
    ], out)
    png = out.with_suffix(".png")
    plot_episode(episode.path, outcome, run.game, pairing, png)
    for line in drawn:
        print(line)
    print(f"{pairing}: {outcome.label} after {steps} steps; wrote {out} and {png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

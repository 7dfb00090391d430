"""Replay one fixed evaluation game of two league members:
``python -m league.replay --run-dir DIR --attacker NAME --team NAME [--game K] [--out PATH]``.

Plays game ``K`` of the run's fixed evaluation games (the ones every evaluation plays, with
deterministic actions; ``K`` from 0 to the run's ``evaluation.episodes`` - 1, others are refused)
between any attacker and any team of the league, scripted or trained,
and writes it as an interactive 3D page (the report's trajectory scene: rotate, zoom, step
through) and as a PNG beside it (``envs.render``). By default both go into the run directory,
named after the pair: ``replay-ATTACKER-vs-TEAM-gameK.html`` and ``.png``.
"""

from __future__ import annotations

import html
import sys
from pathlib import Path

from league.cli import command_parser, count
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
    args = parser.parse_args(argv)
    try:
        run, store = open_run(args.run_dir)
        try:
            players = store.players()
        finally:
            store.close()
        check_game(args.game, run.evaluation.episodes)
        attacker = find_player(players, args.attacker, "attacker")
        team = find_player(players, args.team, "team")
    except (RunDirError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    out = args.out or args.run_dir / f"replay-{attacker.name}-vs-{team.name}-game{args.game}.html"
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
        report_html.figure_div(report_html.trajectory_figure(episode, run.game), "replay"),
    ], out)
    png = out.with_suffix(".png")
    plot_episode(episode.path, outcome, run.game, pairing, png)
    print(f"{pairing}: {outcome.label} after {steps} steps; wrote {out} and {png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

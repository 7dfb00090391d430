"""A run's report: ``python -m league.report --run-dir DIR`` writes ``DIR/report/``.

* ``report.md`` with PNGs: the Table 1 analogue next to the paper's numbers, the payoff
  matrix and its meta-game (Nash mixtures and value, ``league.analysis.nash``), every snapshot against
  the scripted players of the other side by version (``league.analysis.generations``), the exploitability of
  the players and mixtures ``league.exploit`` trained best responses against (with the Nash mixtures' curve over
  the phases, ``exploitability.png``), ratings over training (one panel per side) and a table of every player's
  Elo and Nash-averaged rating, learner win rates and episode returns in the iterations their side learned
  (phases shaded; a line breaks between a learner's phases), and 3D trajectories of a won and a lost game
  for each side (the analogues of the paper's Fig. 3 and Fig. 4), and the learning curves
  (``league.evaluation.learning_curves``: win rate and return over env steps, with reference lines).
* ``index.html``: the same content in one self-contained file (plotly's JavaScript
  inside, so it opens offline), with the trajectories as 3D scenes to rotate, zoom and
  step through (``league.reports.html``).

Evaluation numbers are each pair's newest evaluation in the league database (a pair
played again on the same fixed games is one measurement, not more evidence); a pair the
run never evaluated is played first, on the fixed evaluation games, and recorded as an
evaluation of the run's last iteration (as ``league.evaluate`` records its games).
"""

from __future__ import annotations

import sys
from pathlib import Path

from league.state.run_dir import RunDirError, open_run
from league.cli import command_parser


def build_report(run_dir: Path) -> Path:
    """Play what the report needs and the run lacks (missing evaluation pairs, the recorded
    trajectories), then write ``report/report.md`` and ``report/index.html`` from the store."""
    import torch

    from league.analysis.nash import meta_game_players
    from league.config import saved_run_config
    from league.evaluation.results import evaluate_missing
    from league.evaluation.trajectories import report_trajectories
    from league.reports import html, markdown
    from league.reports.data import gather
    from league.state.store import LeagueStore

    run = saved_run_config(run_dir)
    torch.set_num_threads(run.resources.threads_for(1))  # the games played here run torch in this process
    store = LeagueStore(run_dir)
    try:
        attackers, teams = meta_game_players(store.players())
        evaluate_missing(store, run, run_dir, [(a, t) for a in attackers for t in teams])
        data = gather(store, run, report_trajectories(run, run_dir, store.players()))
    finally:
        store.close()
    out = run_dir / "report"  # made once the games are played: a player that cannot play leaves no empty folder
    out.mkdir(exist_ok=True)
    report = markdown.write_markdown(data, out)
    html.write(data, out / "index.html")
    return report


def main(argv: list[str] | None = None) -> int:
    parser = command_parser(prog="python -m league.report", description=__doc__.splitlines()[0])
    parser.add_argument("--run-dir", type=Path, required=True)
    args = parser.parse_args(argv)
    try:
        open_run(args.run_dir)[1].close()  # checks config.yaml and league.db, one line if damaged
    except RunDirError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    from league.evaluation.engine import MissingModuleError

    try:
        report = build_report(args.run_dir.resolve())
    except MissingModuleError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"report written to {report} and {report.with_name('index.html')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

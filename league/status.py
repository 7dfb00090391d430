"""Print the league table of a run: ``python -m league.status --run-dir DIR``.

Reads only the league database, so it works while ``league.run`` trains. The first line says
whether the run is training (a live process holds its lock), stopped (none does: interrupted,
killed or crashed; the next line says how to resume it) or finished (its final evaluation written).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from rich.console import Console

from league.cli import command_parser
from league.reports.run_standing import (
    exploitability_section, league_table, nash_section, next_step, run_line, status_json,
)
from league.state.run_dir import RunDirError, open_run, run_state, usable_checkpoints


def main(argv: list[str] | None = None) -> int:
    parser = command_parser(prog="python -m league.status", description=__doc__.splitlines()[0])
    parser.add_argument("--run-dir", type=Path, required=True)
    parser.add_argument("--source", choices=["training", "evaluation"], help="count only these games")
    parser.add_argument("--json", action="store_true", help="print the same numbers as one JSON object")
    args = parser.parse_args(argv)
    try:
        _, store = open_run(args.run_dir)
    except RunDirError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    state = run_state(args.run_dir)
    if args.json:
        print(json.dumps(status_json(args.run_dir, store, state, args.source), indent=1))
        store.close()
        return 0
    console = Console() if sys.stdout.isatty() else Console(width=160)
    console.print(run_line(store, state))
    usable, problems = usable_checkpoints(args.run_dir, store)
    hint = next_step(args.run_dir, state, usable)
    if hint:
        console.print(hint, markup=False, soft_wrap=True)
    if usable:
        console.print(f"last checkpoint: iteration {usable[0][0]} at {usable[0][1]}")
    for problem in problems:
        console.print(f"warning: {problem}; a resume falls back to the newest intact checkpoint")
    console.print(league_table(store, args.source))
    for part in nash_section(store) + exploitability_section(store):
        console.print(part)
    store.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())

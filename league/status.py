"""Print the league table of a run: ``python -m league.status --run-dir DIR``.

Reads only the league database, so it works while ``league.run`` trains.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from rich.console import Console

from league.cli import command_parser
from league.reports.status import exploitability_section, league_table, nash_section, run_line, status_json
from league.state.run_dir import RunDirError, open_run, usable_checkpoints


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
    if args.json:
        print(json.dumps(status_json(args.run_dir, store, args.source), indent=1))
        store.close()
        return 0
    console = Console() if sys.stdout.isatty() else Console(width=160)
    console.print(run_line(store))
    usable, problems = usable_checkpoints(args.run_dir, store)
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

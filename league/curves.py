"""Learning curves of several runs of one config: ``python -m league.curves --run-dirs A B C [--out DIR] [--learners NAME...]``.

``DIR`` defaults to ``curves/`` beside the first run directory (``runs/curves`` for
``--run-dirs runs/s0 runs/s1``).

One thin line per run (seed), their mean, and the scripted and untrained reference lines,
in ``OUT/curves.png``, with the last points in ``OUT/curves.md`` (``league.studies.seed_curves``).
The curves are measured while a run trains (``league.evaluation.learning_curves``). Each
run's progress over generations (its snapshots, exploiters' included, against the scripted
players of the other side, from each pair's newest evaluation) is drawn a row per run in
``OUT/generations.png``, with each lineage's first and last snapshot in ``OUT/curves.md``.
``--learners attacker-m2 team`` keeps only those learners' curves (a league of four learners
against 17 curve opponents draws 48 panels); a name no run has a curve of exits 2.
"""

from __future__ import annotations

import sys
from pathlib import Path

from league.cli import command_parser


def default_out(run_dirs: list[Path]) -> Path:
    """``curves/`` beside the first run directory: the runs' parent folder, not the current one."""
    return run_dirs[0].resolve().parent / "curves"


def main(argv: list[str] | None = None) -> int:
    parser = command_parser(
        prog="python -m league.curves",
        description="Learning curves of several runs of one config (seeds): one line per run, their mean, "
        "and the scripted and untrained reference lines, and each run's progress over generations; "
        "writes OUT/curves.png, OUT/generations.png and OUT/curves.md.",
    )
    parser.add_argument("--run-dirs", type=Path, nargs="+", required=True)
    parser.add_argument("--out", type=Path, help="the folder to write (default: curves/ beside the first run directory)")
    parser.add_argument("--learners", nargs="+", metavar="NAME",
                        help="only these learners' curves (e.g. attacker-m2 team; default: every learner's)")
    args = parser.parse_args(argv)
    out = args.out or default_out(args.run_dirs)
    from league.state.run_dir import RunDirError
    from league.studies.seed_curves import study

    try:
        png, md = study(args.run_dirs, out, args.learners)
    except (RunDirError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"curves written to {png} and {md}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

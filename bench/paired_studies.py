"""Two arms' final players, paired by seed: ``python bench/paired_studies.py --base DIR/ARM --other DIR/ARM --seeds S...``.

Reads each seed's run of both arms (``ARM/seed-S``, as ``league.study`` lays them out) and their
rows on the held-out test games (``league.studies.beats_scripted``; a pair not yet played is
played and recorded). The two arms' rows come in one order (each final player against each
opponent, beside its reference), so row i of one is row i of the other: the rows must name the
same scripted opponents, while a trained opponent is each run's own. Prints a Markdown table:
per row the mean over seeds of each arm's rate with its verdict against the reference over
seeds, and the difference (other minus base) paired by seed, with its Student-t 95% interval
and the paired t-test's p.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import torch

from league.analysis.statistics import mean_interval, paired_t_test
from league.state.run_dir import RunDirError
from league.studies.beats_scripted import Row, measure_on_test_games, seed_verdict


def short(name: str) -> str:
    return name.removeprefix("scripted-")


def paired_rows(base: list[list[Row]], other: list[list[Row]]) -> list[str]:
    """Markdown lines: a row per comparison (``base[s][i]`` beside ``other[s][i]`` over seeds ``s``)."""
    lines = ["| trained player | against | base (over seeds) | other (over seeds) | other - base [Student-t 95%] | p |",
             "| --- | --- | --- | --- | --- | --- |"]
    if any(len(b) != len(o) for b, o in zip(base, other)):
        raise ValueError("the two arms' runs have different players: not one config's rows")
    for i, head in enumerate(base[0]):
        mine, theirs = [rows[i] for rows in base], [rows[i] for rows in other]
        if theirs[0].side != head.side or (head.against.startswith("scripted-") and theirs[0].against != head.against):
            raise ValueError(f"row {i}: {head.player} against {head.against} beside {theirs[0].player} against {theirs[0].against}")
        against = short(head.against) if head.against.startswith("scripted-") else "its own final attacker"
        cells = []
        for rows in (mine, theirs):
            _, verdict = seed_verdict([r.gain for r in rows])
            cells.append(f"{np.mean([r.rate for r in rows]):.3f} ({verdict} {'with' if verdict == 'even' else 'than'} "
                         f"{short(rows[0].reference)})")
        differences = [t.rate - m.rate for m, t in zip(mine, theirs)]
        low, high = mean_interval(differences)
        lines.append(f"| {head.side} | {against} | {cells[0]} | {cells[1]} | {np.mean(differences):+.3f} "
                     f"[{low:+.3f}, {high:+.3f}] | {paired_t_test(differences):.3g} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", type=Path, required=True, help="one arm of a study: STUDY/ARM")
    parser.add_argument("--other", type=Path, required=True, help="the arm compared with it: STUDY/ARM")
    parser.add_argument("--seeds", type=int, nargs="+", required=True, help="seeds both arms ran (at least 2)")
    parser.add_argument("--episodes", type=int, default=1000, help="test games per pair (default 1000)")
    args = parser.parse_args(argv)
    if len(set(args.seeds)) < 2:
        print("error: --seeds: at least two seeds to pair", file=sys.stderr)
        return 2
    torch.set_num_threads(1)  # any pair not yet recorded is played here
    try:
        base, other = ([measure_on_test_games(arm / f"seed-{s}", args.episodes, untrained=False)[0] for s in args.seeds]
                       for arm in (args.base, args.other))
        print("\n".join(paired_rows(base, other)))
    except (RunDirError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())

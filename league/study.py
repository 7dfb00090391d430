"""A study over training seeds: ``python -m league.study --config C [C ...] --seeds S [S ...] --out DIR``.

Each config is an arm. For every arm and seed, trains ``league.run --config C --set seed=S``
in ``DIR/ARM/seed-S/`` to its end, each run a Ray Tune trial (``league.studies.trials``: a
finished run is reused, an unfinished one resumed; its output in ``DIR/logs/ARM-seed-S.log``;
a progress line with the time left after each run), then measures the run's final players against every scripted
player of the other side on the held-out test games (``league.studies.beats_scripted``:
the pairs not yet played are played and recorded in the run's store). Prints, per arm, a
table with a column per seed (the rate, its 95% Wilson interval and the verdict within
that seed's games) and over the seeds (the mean with a Student-t 95% interval, and the
paired t-test of trained minus reference), then the runs' training time and speed;
``--page FILE`` also writes them to FILE.

``--jobs K`` trains K runs side by side (default 1); ``--address ADDR`` trains them on the Ray
cluster at ADDR instead (``--cpus-per-run`` CPUs each, as many at once as it holds unless
``--jobs``), so they spread over its nodes; DIR must then be on storage every node shares.
Run again, the same command restores the Tune experiment in ``DIR/.tune`` and reuses the
finished runs.

``--tuning-seeds`` names the seeds that chose the arms' settings: the page prints them,
and a study seed among them is refused, so that the reported seeds are not those that chose.

Exit codes: 0 done; 2 a bad argument (a missing config, a tuning seed among the seeds, a run
directory of another config or that another process is training, no Ray cluster at
``--address``); 1 a training run that failed or was stopped (run again to resume).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import torch

from league.cli import cluster_or_exit, command_parser, count, tuning_seeds_error
from league.config import ConfigError, load_config
from league.studies.beats_scripted import measure_on_test_games, table
from league.studies.runs import speed
from league.studies.trials import TrainingRun, training_exit_code


def study_run(out: Path, config: str, seed: int, overrides: list[str]) -> TrainingRun:
    """An arm's run of one seed: ``OUT/ARM/seed-S``, its output in ``OUT/logs/ARM-seed-S.log``."""
    arm = Path(config).stem
    return TrainingRun(config, out / arm / f"seed-{seed}", (*overrides, f"seed={seed}"), f"{arm}, seed {seed}",
                       out / "logs" / f"{arm}-seed-{seed}.log")


def main(argv: list[str] | None = None) -> int:
    parser = command_parser(prog="python -m league.study", description=__doc__.splitlines()[0])
    parser.add_argument("--config", nargs="+", required=True, help="one config per arm (a name in configs/ or a path)")
    parser.add_argument("--seeds", type=count(0), nargs="+", required=True, help="training seeds (at least 5 for a claim)")
    parser.add_argument("--tuning-seeds", type=count(0), nargs="*", default=[],
                        help="the seeds that chose the arms' settings (printed; refused among --seeds)")
    parser.add_argument("--out", type=Path, required=True, help="the study's directory: OUT/ARM/seed-S/")
    parser.add_argument("--episodes", type=count(1), default=1000, help="test games per pair (default 1000)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="an override for every run of every arm")
    parser.add_argument("--page", type=Path, help="also write the tables to this Markdown file")
    parser.add_argument("--jobs", type=count(1), help="runs trained side by side (default: 1; with --address: "
                        "as many as the cluster's CPUs hold)")
    parser.add_argument("--address", help="a Ray cluster to train the runs on, as Tune trials (default: on this machine)")
    parser.add_argument("--cpus-per-run", type=float, default=2.0, help="CPUs Ray reserves per run (default 2)")
    args = parser.parse_args(argv)
    if args.cpus_per_run <= 0:
        parser.error("--cpus-per-run must be positive")
    chosen = tuning_seeds_error(args.seeds, args.tuning_seeds)
    if chosen:
        print(f"error: {chosen}", file=sys.stderr)
        return 2
    if len(set(args.seeds)) < 2:
        print("error: --seeds: at least two seeds for an interval over seeds", file=sys.stderr)
        return 2
    try:
        for config in args.config:
            load_config(config, [*args.overrides, f"seed={args.seeds[0]}"])
    except ConfigError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if args.address:
        args.address = cluster_or_exit(args.address)
    torch.set_num_threads(1)  # the test games are played in this process, one pair at a time
    started = time.monotonic()
    runs = {(config, seed): study_run(args.out, config, seed, args.overrides) for config in args.config for seed in args.seeds}
    if code := training_exit_code(list(runs.values()), args.out, args.jobs, args.cpus_per_run, args.address):
        return code
    sections = []
    for config in args.config:
        arm = Path(config).stem
        per_seed, speeds = {}, []
        for seed in args.seeds:
            run_dir = runs[config, seed].run_dir
            print(f"measuring {run_dir} on {args.episodes} test games per pair", flush=True)
            per_seed[seed] = measure_on_test_games(run_dir, args.episodes)
            speeds.append(f"- seed {seed}: {speed(run_dir)}")
        sections.append(
            f"## {arm}\n\n`{config}`, seeds {' '.join(map(str, args.seeds))}"
            + (f" (settings chosen on seeds {' '.join(map(str, args.tuning_seeds))})" if args.tuning_seeds else "")
            + (f", overrides {' '.join(args.overrides)}" if args.overrides else "")
            + f"; {args.episodes} test games per pair.\n\n" + table(per_seed) + "\n" + "\n".join(speeds) + "\n"
        )
    text = "\n".join(sections)
    print(text)
    print(f"study done in {time.monotonic() - started:.0f} s")
    if args.page:
        args.page.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())

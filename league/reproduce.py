"""Reproduce the paper's Table 1: ``python -m league.reproduce [--seeds 3] [--episodes 10000]``.

For each reward variant, budget, attacker reward method and seed, trains the attacker
under the paper's protocol (phase 1: against the scripted team) with
``configs/attacker_method{1,2,3}_paper.yaml`` (the paper's rewards, budget and scripted team), evaluates it on the fixed evaluation games, and
writes per variant and budget ``OUT/VARIANT/BUDGET/table1.md`` (per-seed win rates, their
mean with a Student-t 95% interval over seeds, the paper's numbers, and from the learning
curves each attacker's return under its own method next to the best scripted
attacker's) and ``OUT/VARIANT/BUDGET/curves-methodM/`` (``league.studies.seed_curves`` over the seeds).

* Budgets: ``--episodes N ...`` and ``--env-steps N ...``, each value one budget
  (default: ``--episodes 10000``, the paper's).
* Variants: ``--variants paper terminal``; ``paper`` keeps the configs' rewards (no
  terminal reward), ``terminal`` adds ``game.terminal_reward`` = ``--terminal-reward``.
* ``--team`` also trains the team against the frozen attacker (phase 2, same budget).
* Each run is a Ray Tune trial (``league.studies.trials``), its own ``league.run`` process
  and Ray instance, its output in ``OUT/logs/``; a progress line with the time left follows
  each run. Restarts restore the Tune experiment in ``OUT/.tune``: they reuse finished runs
  (``evaluation.md`` written) and resume unfinished ones from their last checkpoint
  (``league.run --resume``).
* ``--jobs K`` trains K runs side by side (default 1).
* ``--address ADDR`` trains the runs on the Ray cluster at ``ADDR`` instead (``--cpus-per-run``
  CPUs each, default 2; as many at once as it holds unless ``--jobs``), so they spread over
  its nodes; ``OUT`` must be on storage every node shares. Each run's node is printed.

The whole two-budget Table 1 (3 methods x 3 seeds x 2 budgets x 2 variants) is one command
(2,000,000 env steps stands for the convergence budget: read it off the learning curves)::

    python -m league.reproduce --seeds 3 --episodes 10000 --env-steps 2000000 --variants paper terminal --jobs 2

Exit codes: 0 done; 2 a bad argument, a run directory another process is training, or no Ray
cluster at ``--address``; 1 a training run that failed or was stopped (its log says why; run
the command again to resume).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from league.cli import cluster_or_exit, command_parser
from league.studies.table_one import Budget, Job, phases_override, table, training_run
from league.studies.trials import training_exit_code

def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = command_parser(
        prog="python -m league.reproduce", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--episodes", type=int, nargs="+", default=[], help="budgets in training episodes per attacker")
    parser.add_argument("--env-steps", type=int, nargs="+", default=[], help="budgets in env steps per attacker")
    parser.add_argument("--variants", nargs="+", default=["paper"], choices=["paper", "terminal"])
    parser.add_argument("--terminal-reward", type=float, default=30.0, help="the terminal variant's win/loss reward")
    parser.add_argument("--team", action="store_true", help="also train the team against the frozen attacker (phase 2)")
    parser.add_argument("--evaluation-episodes", type=int, default=1000)
    parser.add_argument("--methods", type=int, nargs="+", default=[1, 2, 3], choices=[1, 2, 3])
    parser.add_argument("--jobs", type=int, help="runs trained side by side (default: 1; with --address: as many as "
                        "the cluster's CPUs hold)")
    parser.add_argument("--address", help="a Ray cluster to train the runs on, as Tune trials (default: on this machine)")
    parser.add_argument("--cpus-per-run", type=float, default=2.0, help="CPUs Ray reserves per run (default 2)")
    parser.add_argument("--out", type=Path, default=Path("runs/reproduce"))
    parser.add_argument("--set", dest="overrides", action="append", default=[], help="extra config overrides")
    args = parser.parse_args(argv)
    budgets = [*args.episodes, *args.env_steps]
    if args.seeds < 1 or (args.jobs is not None and args.jobs < 1) or args.evaluation_episodes < 1 or any(b < 1 for b in budgets):
        parser.error("--seeds, --jobs, --evaluation-episodes and every budget must be at least 1")
    if args.cpus_per_run <= 0:
        parser.error("--cpus-per-run must be positive")
    if args.terminal_reward <= 0 and "terminal" in args.variants:
        parser.error("--terminal-reward must be positive for the terminal variant")
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if args.address:
        args.address = cluster_or_exit(args.address)
    budgets = [Budget("episodes", n) for n in args.episodes] + [Budget("env_steps", n) for n in args.env_steps]
    budgets = budgets or [Budget("episodes", 10_000)]
    started = time.perf_counter()
    jobs = []
    for variant in args.variants:
        for budget in budgets:
            for method in args.methods:
                for seed in range(args.seeds):
                    overrides = [f"seed={seed}", phases_override(budget, args.team),
                                 f"evaluation.episodes={args.evaluation_episodes}"]
                    if variant == "terminal":
                        overrides.append(f"game.terminal_reward={args.terminal_reward}")
                    run_dir = args.out / variant / budget.label / f"method{method}-seed{seed}"
                    jobs.append(Job(variant, budget, method, seed, run_dir, (*overrides, *args.overrides)))
    logs = args.out / "logs"
    runs = [training_run(j, logs / f"{j.variant}-{j.budget.label}-method{j.method}-seed{j.seed}.log") for j in jobs]
    if code := training_exit_code(runs, args.out, args.jobs, args.cpus_per_run, args.address):
        return code
    wall = time.perf_counter() - started
    from league.studies.seed_curves import study

    for variant in args.variants:
        for budget in budgets:
            done = [j for j in jobs if j.variant == variant and j.budget == budget]
            text = table(args, variant, budget, done, wall)
            out = args.out / variant / budget.label
            (out / "table1.md").write_text(text)
            print(text)
            for method in args.methods:
                dirs = [j.run_dir for j in done if j.method == method]
                try:
                    study(dirs, out / f"curves-method{method}")
                except ValueError as err:  # curves off in these runs
                    print(f"no curves for method {method}: {err}")
    print(f"wall time {wall:.0f} s; tables in {args.out}/VARIANT/BUDGET/table1.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())

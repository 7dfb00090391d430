"""Reproduce the paper's Table 1: ``python -m league.reproduce [--seeds 3] [--episodes 10000]``.

For each reward variant, budget, attacker reward method and seed, trains the attacker
under the paper's protocol (phase 1: against the scripted team) with
``configs/attacker_method{1,2,3}.yaml``, evaluates it on the fixed evaluation games, and
writes per variant and budget ``OUT/VARIANT/BUDGET/table1.md`` (per-seed win rates, their
mean with a bootstrap 95% interval over seeds, the paper's numbers, and from the learning
curves each attacker's return under its own method next to the best scripted
attacker's) and ``OUT/VARIANT/BUDGET/curves-methodM/`` (``league.curves`` over the seeds).

* Budgets: ``--episodes N ...`` and ``--env-steps N ...``, each value one budget
  (default: ``--episodes 10000``, the paper's).
* Variants: ``--variants paper terminal``; ``paper`` keeps the configs' rewards (no
  terminal reward), ``terminal`` adds ``game.terminal_reward`` = ``--terminal-reward``.
* ``--team`` also trains the team against the frozen attacker (phase 2, same budget).
* Restarts reuse finished runs (``evaluation.md`` written) and resume unfinished ones
  from their last checkpoint (``league.run --resume``).
* ``--jobs K`` trains K runs side by side (each its own process and Ray instance; their
  output goes to ``OUT/logs/``).

The whole two-budget Table 1 (3 methods x 3 seeds x 2 budgets x 2 variants) is one command
(2,000,000 env steps stands for the convergence budget: read it off the learning curves)::

    python -m league.reproduce --seeds 3 --episodes 10000 --env-steps 2000000 --variants paper terminal --jobs 2

Exit codes: 0 done; 2 a bad argument, or a run directory another process is training;
1 a training run that failed (its output says why; run the command again to resume).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from league.analysis.statistics import bootstrap_interval
from league.core.payoff import aggregate
from league.report import PAPER_TABLE_1
from league.state.run_dir import RunDirError, lock_run
from league.state.store import LeagueStore

def attacker_win_rate(run_dir: Path, method: int) -> tuple[float, int]:
    """Evaluation win rate of ``attacker-m{method}-v1`` against the paper's scripted team."""
    store = LeagueStore(run_dir)
    try:
        attacker = next(
            p for p in store.players(side="attacker", kind="snapshot") if p.reward_method == method and p.version == 1
        )
        team = next(p for p in store.players(side="team", kind="scripted") if p.is_paper_team)
        wins, games = aggregate(store.newest_evaluation_rows())[(attacker.id, team.id)]
    finally:
        store.close()
    return wins / games, games


@dataclass(frozen=True)
class Budget:
    """A phase budget: ``kind`` is ``episodes`` or ``env_steps``."""

    kind: str
    amount: int

    @property
    def label(self) -> str:
        return f"{self.kind.replace('_', '-')}-{self.amount}"

    def describe(self) -> str:
        return f"{self.amount:,} {self.kind.replace('_', ' ')}"


@dataclass(frozen=True)
class Job:
    variant: str
    budget: Budget
    method: int
    seed: int
    run_dir: Path
    overrides: tuple[str, ...]


def phases_override(budget: Budget, team: bool) -> str:
    phases = [f"{{learner: attacker, {budget.kind}: {budget.amount}}}"]
    if team:
        phases.append(f"{{learner: team, {budget.kind}: {budget.amount}, opponents: latest}}")
    return f"league.phases=[{', '.join(phases)}]"


def finished(run_dir: Path) -> bool:
    """A run whose training and final evaluation completed (``evaluation.md`` is written last)."""
    return (run_dir / "evaluation.md").exists()


def resumable(run_dir: Path) -> bool:
    checkpoints = run_dir / "checkpoints"
    return (run_dir / "league.db").exists() and checkpoints.is_dir() and any(
        not p.name.endswith(".partial") for p in checkpoints.glob("iter_*")
    )


def train(job: Job, log: Path | None) -> None:
    """Train ``job`` to the end (``train_run``)."""
    label = f"{job.variant}, {job.budget.describe()}, method {job.method}, seed {job.seed}"
    train_run(f"attacker_method{job.method}", job.run_dir, job.overrides, label, log)


def say(line: str) -> None:
    """One line in one write: ``--jobs`` trains from several threads, and ``print`` writes
    the text and its newline apart (two runs' lines ran together)."""
    sys.stdout.write(line + "\n")
    sys.stdout.flush()


def train_run(config: str, run_dir: Path, overrides, label: str, log: Path | None = None) -> None:
    """Train a ``league.run`` to the end: skip it when finished, resume it when it has a
    checkpoint, else start it from ``config`` with ``overrides`` (``--set`` items)."""
    if finished(run_dir):
        say(f"reusing {run_dir} (finished)")
        return
    out = open(log, "a") if log else None
    try:
        if resumable(run_dir):
            say(f"resuming {run_dir}")
            subprocess.run([sys.executable, "-m", "league.run", "--resume", str(run_dir)], stdout=out, stderr=out, check=True)
            return
        if run_dir.exists():  # killed before its first checkpoint: nothing to resume
            lock_run(run_dir).release()  # refuses (RunDirError) while another process trains it
            shutil.rmtree(run_dir)
        command = [sys.executable, "-m", "league.run", "--config", config, "--run-dir", str(run_dir)]
        for item in overrides:
            command += ["--set", item]
        say(f"training {label} -> {run_dir}")
        subprocess.run(command, stdout=out, stderr=out, check=True)
    finally:
        if out:
            out.close()


def own_method_returns(run_dir: Path, method: int) -> tuple[float, float, str] | None:
    """From the learning curves against the paper's team: the attacker's return under its own
    method at the last point, and the best scripted attacker's on the same games (with the run's
    terminal reward); ``None`` when the run recorded no curve."""
    from league.curves import read_curves
    from league.state.run_dir import open_run

    run, store = open_run(run_dir)
    try:
        curves = read_curves(store)
    finally:
        store.close()
    paper_team = "scripted-avoid_attacker+pure_pursuit"
    curve = next((c for c in curves if c.learner.reward_method == method and c.opponent.name == paper_team), None)
    if curve is None:
        return None
    reward = run.game.terminal_reward
    scripted = [(stats.attacker_return(method, reward), name) for kind, name, stats in curve.references if kind == "scripted"]
    best, name = max(scripted)
    return curve.stats[-1].attacker_return(method, reward), best, f"{name.removeprefix('scripted-')}, {curve.stats[-1].games} games"


def table(args: argparse.Namespace, variant: str, budget: Budget, jobs: list[Job], wall: float) -> str:
    rates: dict[int, list[float]] = {}
    returns: dict[int, list[tuple[float, float, str]]] = {}
    for job in jobs:
        rate, games = attacker_win_rate(job.run_dir, job.method)
        rates.setdefault(job.method, []).append(rate)
        curve = own_method_returns(job.run_dir, job.method)
        if curve is not None:
            returns.setdefault(job.method, []).append(curve)
    terminal = f"a terminal reward of +-{args.terminal_reward:g}" if variant == "terminal" else "the paper's rewards (no terminal reward)"
    lines = [
        f"# Table 1 analogue: {variant}, {budget.describe()}",
        "",
        f"Attacker win rate against the paper's scripted team (T to the terminal avoiding A, D pursuing A), "
        f"{args.evaluation_episodes} fixed evaluation games per seed, {budget.describe()} of training per attacker, "
        f"{terminal}, {args.seeds} seeds; mean with a bootstrap 95% interval over seeds. "
        f"Overrides: {args.overrides or 'none'}. Wall time of this invocation (finished runs reused): {wall:.0f} s.",
        "",
        "| method | per seed | mean | 95% bootstrap interval | paper (100 rounds) | own-method return per seed "
        "(last curve point) | best scripted attacker's return |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    means = {}
    for method, values in rates.items():
        low, high = bootstrap_interval(values)
        means[method] = float(np.mean(values))
        per_seed = ", ".join(f"{v:.3f}" for v in values)
        own = ", ".join(f"{r:.2f}" for r, _, _ in returns.get(method, [])) or "no curves"
        best = returns[method][0] if returns.get(method) else None
        scripted = f"{best[1]:.2f} ({best[2]})" if best else ""
        lines.append(
            f"| {method} | {per_seed} | {means[method]:.3f} | [{low:.3f}, {high:.3f}] | {PAPER_TABLE_1[method]} | {own} | {scripted} |"
        )
    order = " > ".join(f"method {m}" for m in sorted(means, key=lambda m: -means[m]))
    lines += ["", f"Ordering here: {order}. The paper's: method 2 > method 3 > method 1."]
    return "\n".join(lines) + "\n"


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
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
    parser.add_argument("--jobs", type=int, default=1, help="runs trained side by side")
    parser.add_argument("--out", type=Path, default=Path("runs/reproduce"))
    parser.add_argument("--set", dest="overrides", action="append", default=[], help="extra config overrides")
    args = parser.parse_args(argv)
    budgets = [*args.episodes, *args.env_steps]
    if args.seeds < 1 or args.jobs < 1 or args.evaluation_episodes < 1 or any(b < 1 for b in budgets):
        parser.error("--seeds, --jobs, --evaluation-episodes and every budget must be at least 1")
    if args.terminal_reward <= 0 and "terminal" in args.variants:
        parser.error("--terminal-reward must be positive for the terminal variant")
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
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
    logs.mkdir(parents=True, exist_ok=True)
    try:
        if args.jobs == 1:
            for job in jobs:
                train(job, None)
        else:
            with ThreadPoolExecutor(args.jobs) as pool:
                names = [logs / f"{j.variant}-{j.budget.label}-method{j.method}-seed{j.seed}.log" for j in jobs]
                for future in [pool.submit(train, job, log) for job, log in zip(jobs, names)]:
                    future.result()
    except RunDirError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except subprocess.CalledProcessError as err:
        print(f"error: training failed (exit {err.returncode}): {' '.join(err.cmd[1:])}; run this command again to resume",
              file=sys.stderr)
        return 1
    wall = time.perf_counter() - started
    from league.curves import study

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

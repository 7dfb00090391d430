"""Reproduce the paper's Table 1: ``python -m league.reproduce [--seeds 3] [--episodes 10000]``.

For each attacker reward method and seed, trains the attacker under the paper's protocol
(phase 1: against the scripted team for ``--episodes`` episodes) with
``configs/attacker_method{1,2,3}.yaml``, evaluates it on the fixed evaluation games, and
writes ``OUT/table1.md``: per-seed win rates, their mean with a bootstrap 95% interval
over seeds, and the paper's numbers. Finished runs in ``OUT`` are reused, so an
interrupted reproduction continues where it stopped.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from league.payoff import aggregate
from league.report import PAPER_TABLE_1
from league.store import LeagueStore

BOOTSTRAP_SAMPLES = 10_000


def bootstrap_interval(values: list[float], seed: int = 0) -> tuple[float, float]:
    """95% percentile interval of the mean over resampled seeds."""
    rng = np.random.default_rng(seed)
    data = np.asarray(values)
    means = data[rng.integers(0, len(data), size=(BOOTSTRAP_SAMPLES, len(data)))].mean(axis=1)
    return float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))


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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m league.reproduce", description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--episodes", type=int, default=10_000, help="training episodes per attacker")
    parser.add_argument("--evaluation-episodes", type=int, default=1000)
    parser.add_argument("--methods", type=int, nargs="+", default=[1, 2, 3], choices=[1, 2, 3])
    parser.add_argument("--out", type=Path, default=Path("runs/reproduce"))
    parser.add_argument("--set", dest="overrides", action="append", default=[], help="extra config overrides")
    args = parser.parse_args(argv)
    if args.seeds < 1 or args.episodes < 1:
        parser.error("--seeds and --episodes must be at least 1")
    started = time.perf_counter()
    rates: dict[int, list[float]] = {}
    for method in args.methods:
        for seed in range(args.seeds):
            run_dir = args.out / f"method{method}-seed{seed}"
            if not (run_dir / "evaluation.md").exists():
                if run_dir.exists():
                    subprocess.run(["rm", "-rf", str(run_dir)], check=True)  # an unfinished run: start it again
                command = [
                    sys.executable, "-m", "league.run", "--config", f"attacker_method{method}", "--run-dir", str(run_dir),
                    "--set", f"seed={seed}", "--set", f"league.phases=[{{learner: attacker, episodes: {args.episodes}}}]",
                    "--set", f"evaluation.episodes={args.evaluation_episodes}",
                ]
                for item in args.overrides:
                    command += ["--set", item]
                print(f"training method {method}, seed {seed} -> {run_dir}", flush=True)
                subprocess.run(command, check=True)
            rate, games = attacker_win_rate(run_dir, method)
            rates.setdefault(method, []).append(rate)
            print(f"method {method} seed {seed}: {rate:.3f} over {games} games", flush=True)
    wall = time.perf_counter() - started
    lines = [
        "# Table 1 analogue",
        "",
        f"Attacker win rate against the paper's scripted team (T to the terminal avoiding A, D pursuing A), "
        f"{args.evaluation_episodes} fixed evaluation games per seed, {args.episodes} training episodes per attacker, "
        f"{args.seeds} seeds; mean with a bootstrap 95% interval over seeds. Overrides: {args.overrides or 'none'}. "
        f"Wall time of this command: {wall:.0f} s.",
        "",
        "| method | per seed | mean | 95% bootstrap interval | paper (100 rounds) |",
        "| --- | --- | --- | --- | --- |",
    ]
    means = {}
    for method, values in rates.items():
        low, high = bootstrap_interval(values)
        means[method] = float(np.mean(values))
        per_seed = ", ".join(f"{v:.3f}" for v in values)
        lines.append(f"| {method} | {per_seed} | {means[method]:.3f} | [{low:.3f}, {high:.3f}] | {PAPER_TABLE_1[method]} |")
    order = " > ".join(f"method {m}" for m in sorted(means, key=lambda m: -means[m]))
    lines += ["", f"Ordering here: {order}. The paper's: method 2 > method 3 > method 1."]
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "table1.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())

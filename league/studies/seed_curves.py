"""Learning curves of several runs of one config (seeds): their plot and a summary table, and
each run's progress over generations (its snapshots, exploiters' included, against the
scripted panel: ``league.analysis.generations``) with each lineage's first and last snapshot
(``python -m league.curves --run-dirs A B C --out DIR``; ``league.reproduce`` per method)."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np

from league.analysis.generations import GenerationLine
from league.evaluation.learning_curves import Curve, GameStats, read_curves
from league.reports.data import run_generations
from league.reports.plots import plot_curves, quantities, runs_generations_plot
from league.state.run_dir import open_run


def summary_table(groups: list[list[Curve]], run_names: list[str], terminal_reward: float) -> str:
    """Markdown: each group's last point per run, its mean, and the reference values (means over runs)."""
    lines = []
    for group in groups:
        learner, opponent = group[0].learner, group[0].opponent
        lines += [f"### {learner.name} vs {opponent.name}", "",
                  "| run | env steps | win rate | 95% interval | " + " | ".join(q.title for q in quantities(learner)[1:]) + " |",
                  "| --- | --- | --- | --- | " + " | ".join("---" for _ in quantities(learner)[1:]) + " |"]
        for name, curve in zip(run_names, group):
            last = curve.stats[-1]
            low, high = last.win_interval(learner.side)
            others = " | ".join(f"{q.value(last, curve.learner, terminal_reward):.3f}" for q in quantities(learner)[1:])
            lines.append(f"| {name} | {curve.env_steps[-1]:,} | {last.win_rate(learner.side):.3f} | [{low:.3f}, {high:.3f}] | {others} |")
        refs: dict[str, list[GameStats]] = defaultdict(list)
        for curve in group:
            for kind, name, stats in curve.references:
                refs["untrained (version 0)" if kind == "untrained" else name].append(stats)
        for name, stats in sorted(refs.items()):
            values = " | ".join(
                f"{np.mean([q.value(s, learner, terminal_reward) for s in stats]):.3f}" for q in quantities(learner)[1:]
            )
            rate = np.mean([s.win_rate(learner.side) for s in stats])
            lines.append(f"| reference: {name} | | {rate:.3f} | | {values} |")
        lines.append("")
    return "\n".join(lines)


def snapshot_cells(line: GenerationLine, k: int) -> str:
    """The ``k``-th evaluated snapshot of a line: version, win rate and its Wilson interval."""
    low, high = line.intervals[k]
    return f"v{line.versions[k]} | {line.rates[k]:.3f} | [{low:.3f}, {high:.3f}]"


def progress_table(generations: list[tuple[list[GenerationLine], list[str]]], run_names: list[str]) -> str:
    """Markdown: per run (its lines and missing points), each lineage's first and last evaluated
    snapshot against each scripted opponent (the snapshot's win rate), and the points not evaluated."""
    lines = ["## Progress over generations", "",
             "Each run's snapshots against the scripted players of the other side (`generations.png`, one row "
             "per run, exploiters dashed): the snapshot's win rate, newest evaluation of each pair.", ""]
    for name, (run_lines, missing) in zip(run_names, generations):
        lines += [f"### {name}", "",
                  "| lineage | opponent | first | win rate | 95% interval | last | win rate | 95% interval |",
                  "| --- | --- | --- | --- | --- | --- | --- | --- |"]
        for line in run_lines:
            points = (f"{snapshot_cells(line, 0)} | {snapshot_cells(line, -1)}" if line.versions
                      else "not evaluated | | | | |")
            lines.append(f"| {line.lineage} | {line.opponent} | {points} |")
        lines += ["", *(f"* {text}" for text in missing), ""] if missing else [""]
    return "\n".join(lines)


def study(run_dirs: list[Path], out: Path, learners: list[str] | None = None) -> tuple[Path, Path]:
    """Curves of several runs of one config: ``OUT/curves.png`` and ``OUT/curves.md``, and their
    progress over generations, a row per run, in ``OUT/generations.png``. ``learners``: only these
    learners' curves (names as ``attacker-m2``, ``team``); ``None``: every learner's."""
    per_run: list[dict[tuple[str, str], Curve]] = []
    generations = []
    configs = []
    for run_dir in run_dirs:
        run, store = open_run(run_dir)
        try:
            per_run.append({(c.learner.name, c.opponent.name): c for c in read_curves(store)})
            generations.append(run_generations(store))
        finally:
            store.close()
        configs.append(run)
    keys = [k for k in per_run[0] if all(k in curves for curves in per_run)]
    if not keys:
        raise ValueError(f"the runs have no learning curve in common ({', '.join(map(str, run_dirs))})")
    if learners is not None:
        unknown = sorted(set(learners) - {learner for learner, _ in keys})
        if unknown:
            raise ValueError(f"--learners: no curves of {', '.join(unknown)} in these runs "
                             f"(they have {', '.join(sorted({learner for learner, _ in keys}))})")
        keys = [k for k in keys if k[0] in learners]
    terminal = {run.game.terminal_reward for run in configs}
    if len(terminal) > 1:
        raise ValueError(f"the runs use different terminal rewards {sorted(terminal)}: not one config")
    groups = [[curves[k] for curves in per_run] for k in keys]
    out.mkdir(parents=True, exist_ok=True)
    (reward,) = terminal
    names = [Path(d).name for d in run_dirs]
    plot_curves(groups, reward, f"{configs[0].name}: {len(run_dirs)} runs", out / "curves.png")
    runs_generations_plot([(name, lines) for name, (lines, _) in zip(names, generations)], out / "generations.png")
    text = f"# Learning curves of {len(run_dirs)} runs\n\nRuns: {', '.join(map(str, run_dirs))}. " \
           f"Last point of each run on the fixed dev games; references are means over the runs.\n\n" + summary_table(groups, names, reward) \
           + "\n" + progress_table(generations, names)
    (out / "curves.md").write_text(text)
    return out / "curves.png", out / "curves.md"

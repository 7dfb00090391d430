"""Is the league any good? The league-quality study: ``python bench/league_quality.py``.

Trains one run per arm from ``configs/selfplay_league.yaml`` with the same game, PPO
settings and env-step budget per side, then compares the final players of each side:

| arm                | the team learns against                                    |
| ------------------ | ---------------------------------------------------------- |
| ``protocol``       | the frozen attacker of phase 1 (which learned against the scripted teams), one phase |
| ``naive``          | the other side's newest snapshot only, phases in turn      |
| ``league``         | PFSP over the other side's scripted players and snapshots  |
| ``league-exploiters`` | as ``league``, with a main exploiter on each side (``league.exploiters``) |
| ``league-variance`` | as ``league``, PFSP weighting ``variance``, x(1 - x), instead of ``squared`` |
| ``league-psro``    | as ``league``, opponents by PSRO's rule (``pfsp: nash``): the Nash mixture of the frozen players' meta-game |

Every arm: method-2 attacker reward with a terminal reward of +-``--terminal-reward`` (so
both sides learn to win), ``--phases`` alternating phases of ``--phase-env-steps``
(``protocol``: two phases of half the total each), and phases that end only on their
budget, so each side samples the same env steps in every arm. With exploiters a phase ends
on its learner's env steps and the exploiter samples about as many again, so that arm's
phases get half the budget: the same total per side, half of it the learner's.

Each arm is trained once per ``--train-seeds`` seed (``OUT/ARM/seed-S``); an arm's runs
differ only in their seed. For each run's final team (and final attacker): the win rate
against every scripted player of the other side and every arm's final player of the other
side of the same training seed on the same ``--episodes`` fixed games (Wilson 95%
intervals), and its exploitability: ``--seeds`` best responses (``league.exploit``; their
mean) of ``--br-env-steps`` each, against a team, or ``--team-br-env-steps`` (a team's best
response to an attacker: the team learns more slowly). Per arm, the mean exploitability over training seeds with
its Student-t 95% interval over the training seeds (``mean_interval``). Writes ``OUT/league_quality.md``.
Each run is a Ray Tune trial (``league.studies.trials``; its output in ``OUT/ARM-seed-S.log``),
``--jobs`` at a time, or on the Ray cluster at ``--address`` (``--cpus-per-run`` CPUs each; OUT
on storage every node shares). Restarts reuse finished runs and best responses (and resume
unfinished runs).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from envs.scenarios import evaluation_scenarios
from league.cli import cluster_or_exit
from league.analysis.exploitability import exploitability
from league.evaluation.engine import play_fixed_games, policies_of
from league.analysis.statistics import SEED_INTERVAL, mean_interval, wilson_interval
from league.core.payoff import wins_of
from league.core.players import Player, other_side
from league.studies.trials import RunFailed, TrainingRun, train_runs
from league.state.run_dir import RunDirError, open_run

ARMS = ("protocol", "naive", "league", "league-exploiters", "league-variance", "league-psro")
PFSP_OF_ARM = {"league-variance": "variance", "league-psro": "nash"}  # the others: squared


def arm_overrides(arm: str, args: argparse.Namespace, seed: int) -> list[str]:
    """The ``--set`` overrides of ``configs/selfplay_league.yaml`` for one arm's run of one training seed."""
    common = [
        "game.attacker_reward=2", f"game.terminal_reward={args.terminal_reward}", "league.attacker_reward_methods=[2]",
        f"evaluation.episodes={args.episodes}", f"seed={seed}",
        # The arms' exploiters train beside their learners (or not at all), not in a final phase.
        "league.exploiter_phases=all",
    ]
    per_side = args.phases // 2 * args.phase_env_steps
    if arm == "protocol":
        phases = [f"{{learner: attacker, env_steps: {per_side}, opponents: scripted}}",
                  f"{{learner: team, env_steps: {per_side}, opponents: latest}}"]
        return [*common, "league.mode=protocol", "league.exploiters=[]", f"league.phases=[{', '.join(phases)}]"]
    if arm == "naive":
        phases = [f"{{learner: {'attacker' if i % 2 == 0 else 'team'}, env_steps: {args.phase_env_steps}, "
                  f"opponents: {'scripted' if i == 0 else 'latest'}}}" for i in range(args.phases)]
        return [*common, "league.mode=protocol", "league.exploiters=[]", f"league.phases=[{', '.join(phases)}]"]
    exploiters = arm == "league-exploiters"
    return [*common, "league.mode=selfplay", f"league.selfplay_phases={args.phases}",
            f"league.phase_env_steps={args.phase_env_steps // 2 if exploiters else args.phase_env_steps}",
            "league.team_phase_env_steps=null",  # both sides' phases: the same budget
            "league.snapshot_win_rate=1.0", f"league.min_phase_episodes={10**9}",  # a phase ends on its budget only
            f"league.exploiters=[{'attacker, team' if exploiters else ''}]",
            f"league.pfsp={PFSP_OF_ARM.get(arm, 'squared')}"]


def final_player(players: list[Player], side: str, kind: str = "snapshot") -> Player | None:
    """The side's newest snapshot of its main learner (``kind="exploiter_snapshot"``: of its
    exploiter); for attackers, the method-2 one."""
    snapshots = [p for p in players if p.side == side and p.kind == kind and p.reward_method in (None, 2)]
    return max(snapshots, key=lambda p: p.version, default=None)


def br_budget(player: Player, args: argparse.Namespace) -> int:
    """The env steps of each best response to ``player``: a team's to an attacker, an attacker's to a team."""
    return args.team_br_env_steps if player.side == "attacker" else args.br_env_steps


def exploitability_of(run_dir: Path, player: Player, args: argparse.Namespace):
    """Train the missing best responses against ``player`` (``league.exploit``), then read them all back."""
    budget = br_budget(player, args)
    _, store = open_run(run_dir)
    try:
        done = [p for p in store.players(kind="best_response")
                if p.parent == player.id and p.env_step_budget == budget]
    finally:
        store.close()
    if len(done) < args.seeds:
        print(f"exploiting {run_dir.name}/{player.name}: {args.seeds - len(done)} best response(s)", flush=True)
        subprocess.run([sys.executable, "-m", "league.exploit", "--run-dir", str(run_dir), "--player", player.name,
                        "--env-steps", str(budget), "--seeds", str(args.seeds - len(done)),
                        "--episodes", str(args.episodes)], check=True)
    _, store = open_run(run_dir)
    try:
        players = store.players()
        found = [e for e in exploitability(players, store.newest_evaluation_rows())
                 if e.exploited.id == player.id and e.budget == budget]
    finally:
        store.close()
    return found[0]


def win_cell(wins: int, games: int) -> str:
    low, high = wilson_interval(wins, games)
    return f"{wins / games:.3f} [{low:.2f}, {high:.2f}]"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("runs/league_quality"))
    parser.add_argument("--jobs", type=int, help="runs trained side by side (default: 1; with --address: as many as "
                        "the cluster's CPUs hold)")
    parser.add_argument("--address", help="train the arms as Tune trials on this Ray cluster (OUT on shared storage)")
    parser.add_argument("--cpus-per-run", type=float, default=2.0, help="CPUs Ray reserves per run (default 2)")
    parser.add_argument("--arms", nargs="+", default=list(ARMS), choices=ARMS)
    parser.add_argument("--phases", type=int, default=6, help="alternating phases (even: both sides the same budget)")
    parser.add_argument("--phase-env-steps", type=int, default=200_000)
    parser.add_argument("--terminal-reward", type=float, default=30.0)
    parser.add_argument("--br-env-steps", type=int, default=200_000, help="each best response's training budget")
    parser.add_argument("--team-br-env-steps", type=int, help="a team's best response's budget (default: --br-env-steps)")
    parser.add_argument("--seeds", type=int, default=3, help="best responses per final player")
    parser.add_argument("--episodes", type=int, default=1000, help="fixed evaluation games per pair")
    parser.add_argument("--train-seeds", type=int, nargs="+", default=[0, 1, 2], help="each arm's training seeds")
    parser.add_argument("--sides", nargs="+", default=["team", "attacker"], choices=["team", "attacker"],
                        help="whose exploitability to measure (teams first)")
    args = parser.parse_args(argv)
    args.team_br_env_steps = args.team_br_env_steps or args.br_env_steps
    if args.phases < 2 or args.phases % 2 or min(args.phase_env_steps, args.br_env_steps, args.team_br_env_steps, args.seeds, args.episodes) < 1:
        parser.error("--phases must be even and at least 2; budgets, --seeds and --episodes at least 1")
    if (args.jobs is not None and args.jobs < 1) or args.cpus_per_run <= 0:
        parser.error("--jobs must be at least 1 and --cpus-per-run positive")
    if args.address:
        args.address = cluster_or_exit(args.address)
    args.out.mkdir(parents=True, exist_ok=True)
    walls_file = args.out / "wall_times.json"

    def read_walls() -> dict[str, float]:
        return json.loads(walls_file.read_text()) if walls_file.exists() else {}
    runs = [(arm, seed, args.out / arm / f"seed-{seed}") for arm in args.arms for seed in args.train_seeds]

    def training_run(arm: str, seed: int, run_dir: Path) -> TrainingRun:
        """One arm's run of one training seed."""
        return TrainingRun("selfplay_league", run_dir, tuple(arm_overrides(arm, args, seed)), f"{arm} seed {seed}",
                           args.out / f"{arm}-seed-{seed}.log")

    try:
        trained = train_runs([training_run(*run) for run in runs], args.out, args.jobs, args.cpus_per_run, args.address)
    except RunDirError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except RunFailed as err:
        print(f"error: {err}; run this command again to resume", file=sys.stderr)
        return 1
    # read again: other invocations (other arms or seeds, into the same OUT) may have added theirs
    walls_file.write_text(json.dumps({**read_walls(), **{t.run.label: t.seconds for t in trained if not t.reused}}, indent=1))

    finals: dict[tuple[str, int], dict[str, Player]] = {}
    exploiter_steps: dict[tuple[str, int], dict[str, int]] = {}
    for arm, seed, run_dir in runs:
        run, store = open_run(run_dir)
        try:
            players = store.players()
        finally:
            store.close()
        finals[arm, seed] = {side: final_player(players, side) for side in ("attacker", "team")}
        exploiter_steps[arm, seed] = {side: getattr(final_player(players, side, "exploiter_snapshot"), "env_steps", 0)
                                      for side in ("attacker", "team")}
        # every run has the same game and scripted players (arm_overrides changes only the league and the seed)
        scripted = {side: [p for p in players if p.side == side and p.kind == "scripted"] for side in ("attacker", "team")}

    positions = evaluation_scenarios(run.game.scenario, args.episodes)
    lines = [
        "# Is the league any good? (bench/league_quality.py)", "",
        f"Settings: `selfplay_league.yaml`, method-2 attacker, terminal reward +-{args.terminal_reward:g}, "
        f"{args.phases // 2 * args.phase_env_steps:,} env steps per side in every arm, training seeds "
        f"{', '.join(map(str, args.train_seeds))}; {args.episodes} fixed evaluation games per pair (Wilson 95%); "
        f"exploitability: {args.seeds} best responses per final player, {args.br_env_steps:,} env steps each against "
        f"a team, {args.team_br_env_steps:,} against an attacker "
        f"(their mean), and per arm the mean over training seeds ({SEED_INTERVAL}). Wall time per "
        "training run: " + ", ".join(f"{label} {seconds:.0f} s" for label, seconds in read_walls().items()) + ".",
    ]
    for side in args.sides:
        other = other_side(side)
        titles = [p.name.removeprefix("scripted-") for p in scripted[other]] + [f"{arm}'s final {other}" for arm in args.arms]
        lines += ["", f"## Final {side}s: win rate against the other side (same training seed), and exploitability", "",
                  f"| arm | seed | {side} | env steps (learner + exploiter) | " + " | ".join(titles) + " | exploitability (per best response) |",
                  "| --- " * (len(titles) + 5) + "|"]
        by_arm: dict[str, list[float]] = {arm: [] for arm in args.arms}
        for arm, seed, run_dir in runs:
            player = finals[arm, seed][side]
            # (player, its run directory): a scripted player needs none, a learned one its module from there
            columns = [(p, None) for p in scripted[other]] + [(finals[a, seed][other], args.out / a / f"seed-{seed}") for a in args.arms]
            cells = []
            for opponent, home in columns:
                pair = {**policies_of(player, run_dir), **policies_of(opponent, home)}
                result = play_fixed_games(run.game, positions, pair)
                wins = wins_of(side, int(result.attacker_wins.sum()), args.episodes)
                cells.append(win_cell(wins, args.episodes))
            found = exploitability_of(run_dir, player, args)
            by_arm[arm].append(found.mean)
            seeds = ", ".join(f"{r.win_rate:.3f}" for r in found.results)
            steps = f"{player.env_steps:,}" + (f" + {exploiter_steps[arm, seed][side]:,}" if exploiter_steps[arm, seed][side] else "")
            lines.append(f"| {arm} | {seed} | {player.name} | {steps} | " + " | ".join(cells) + f" | {found.mean:.3f} ({seeds}) |")
            print(lines[-1], flush=True)
        lines += ["", f"Exploitability of the final {side}, mean over training seeds:", "",
                  f"| arm | mean | {SEED_INTERVAL} |", "| --- | --- | --- |"]
        for arm, values in by_arm.items():
            spread = "[{:.3f}, {:.3f}]".format(*mean_interval(values)) if len(values) > 1 else "(one seed)"
            lines.append(f"| {arm} | {np.mean(values):.3f} | {spread} |")
    (args.out / "league_quality.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())

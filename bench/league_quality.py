"""Does the league make less exploitable players than simpler training? ``python bench/league_quality.py``.

Trains one run per arm and training seed from ``--config`` (default ``selfplay_league``), the
arms differing only in whom each side's learner trains against:

| arm | the learner of each side trains against |
| --- | --- |
| ``protocol`` | the paper's protocol: the attacker the scripted teams for half the budget, then the team that attacker's final snapshot |
| ``naive`` | the other side's newest snapshot only, phases in turn (the first attacker phase: the scripted teams) |
| ``league`` | the config's league: PFSP over the other side's scripted players and snapshots, with the config's exploiters (as shipped: an attacker exploiter in a last phase, against the final team) |
| ``league-do`` | as ``league``, with PSRO's double-oracle step (``league.double_oracle``): at each phase's end a best response of that phase's side, trained against the other side's Nash mixture, joins the pool |
| ``league-do-rm`` | as ``league-do``, the best responses against the other side's regret-matching distribution (``meta_solver: regret_matching``) |

Every arm: one attacker (reward method 2), a terminal reward of +-``--terminal-reward`` (both
sides learn to win), ``--phases`` alternating phases of ``--phase-env-steps``
(``protocol``: two phases of half the total each), each ending on its budget only, so each
side's learner samples the same env steps in every arm. The double-oracle best responses
sample ``--do-env-steps`` each on top of that (one per phase, of that phase's side), and the
league arms' exploiters their own phase's: the page reports both beside the learner's.

Seeds: each arm is trained once per ``--seeds`` seed (``OUT/ARM/seed-S``, its output in
``OUT/logs/ARM-seed-S.log``); an arm's runs differ only in their seed. ``--tuning-seeds``
names the seeds that chose the config's settings: printed on the page, refused among
``--seeds``.

Measured on the held-out test games (``--episodes`` of them, ``envs.scenarios``), which no
training, curve or tuning played:

1. each run's final player of each side against every scripted player of the other side
   (recorded in the run's store, source ``test``) and against every arm's final player of the
   other side of the same training seed: win rates with Wilson 95% intervals; and the side's
   Nash mixture (``nash-team``) against every scripted player: its members' rates by their weights;
2. its exploitability: ``--br-seeds`` best responses (``python -m league.exploit --games test
   --json``) against (a) the final snapshot and (b) the side's Nash mixture of the run's final
   meta-game (``nash-team``, ``nash-attacker``), each of ``--br-env-steps`` (a team's, against
   an attacker: ``--team-br-env-steps``); an attacker from scratch, a team both from scratch
   (where many never learned to win, docs/results/league-quality.md) and from the run's team
   prior, the start whose learning curves end higher (dev games) counting (``--team-br-start``):
   their mean win rate, its margin
   over the best league member of the other side (chosen on the dev games, measured on the
   test games) and how many learning curves were flat at the end (else the figure is a lower
   bound). Over the training seeds, per arm: the mean with its Student-t 95% interval, and the
   paired t-test over the training seeds of the arm minus ``league``.

Writes ``OUT/league_quality.md`` and its figure ``OUT/league_quality.png`` (each seed's exploitability per arm,
and the arm's mean with its interval). Each run is a Ray Tune trial (``league.studies.trials``),
``--jobs`` at a time, or on the Ray cluster at ``--address`` (``--cpus-per-run`` CPUs each;
OUT on storage every node shares); the measurements then run on this machine, and the best
responses too, those of ``--jobs`` runs at a time (one run's one after another: ``league.exploit``
holds its run directory's lock). Run again, the same command reuses finished runs (and resumes
unfinished ones), the recorded test games and the best responses whose results it kept
(``OUT/ARM/seed-S/exploitability/*.json``, one ``league.exploit --json`` output per call).

Exit codes: 0 done; 2 a bad argument (an arm's config that does not load, a tuning seed among
the seeds, a run directory of another config); 1 a training run or a best response that failed
(run again to resume).
"""

from __future__ import annotations

import shlex
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from envs.scenarios import evaluation_scenarios
from league.analysis.mixtures import store_mixture
from league.analysis.statistics import SEED_INTERVAL, mean_interval, paired_t_test, wilson_interval
from league.cli import cluster_or_exit, command_parser, count, tuning_seeds_error
from league.config import ConfigError, load_config
from league.core.payoff import wins_of
from league.core.players import Player, other_side
from league.evaluation.engine import play_fixed_games, policies_of
from league.evaluation.results import test_game_stats
from league.state.run_dir import open_run, read_config
from league.studies.exploitation import Exploited, exploited
from league.studies.runs import speed
from league.studies.trials import TrainingRun, training_exit_code

ARMS = ("protocol", "naive", "league", "league-do", "league-do-rm")
REFERENCE_ARM = "league"  # the arm the others are tested against
SIDES = ("team", "attacker")
TARGETS = ("final", "nash")  # what best responses train against: the final snapshot, the side's Nash mixture


def arm_overrides(arm: str, args, seed: int) -> list[str]:
    """The ``--set`` overrides of ``args.config`` for one arm's run of one training seed: ``args.overrides``
    first, then the arm's (which make the comparison, so they win)."""
    common = [
        *args.overrides, "game.attacker_reward=2", f"game.terminal_reward={args.terminal_reward}",
        "league.attacker_reward_methods=[2]",
        "league.double_oracle.env_steps=0", "league.double_oracle.meta_solver=nash",
        f"evaluation.episodes={args.episodes}", f"seed={seed}",
    ]
    per_side = args.phases // 2 * args.phase_env_steps
    protocol_mode = ["league.mode=protocol", "league.exploiters=[]", "league.exploiter_phases=all"]  # exploiters: self-play only
    if arm == "protocol":
        phases = [f"{{learner: attacker, env_steps: {per_side}, opponents: scripted}}",
                  f"{{learner: team, env_steps: {per_side}, opponents: latest}}"]
        return [*common, *protocol_mode, f"league.phases=[{', '.join(phases)}]"]
    if arm == "naive":
        phases = [f"{{learner: {'attacker' if i % 2 == 0 else 'team'}, env_steps: {args.phase_env_steps}, "
                  f"opponents: {'scripted' if i == 0 else 'latest'}}}" for i in range(args.phases)]
        return [*common, *protocol_mode, f"league.phases=[{', '.join(phases)}]"]
    selfplay = [*common, "league.mode=selfplay", f"league.selfplay_phases={args.phases}",
                f"league.phase_env_steps={args.phase_env_steps}", "league.team_phase_env_steps=null",
                "league.snapshot_win_rate=1.0", f"league.min_phase_episodes={10**9}"]  # a phase ends on its budget only
    if arm == "league":
        return selfplay
    oracle = [f"league.double_oracle.env_steps={args.do_env_steps}"]
    if arm == "league-do-rm":
        oracle.append("league.double_oracle.meta_solver=regret_matching")
    return [*selfplay, *oracle]


def training_run(arm: str, seed: int, args) -> TrainingRun:
    """One arm's run of one seed: ``OUT/ARM/seed-S``, its output in ``OUT/logs/ARM-seed-S.log`` (as ``league.study``)."""
    return TrainingRun(args.config, args.out / arm / f"seed-{seed}", tuple(arm_overrides(arm, args, seed)),
                       f"{arm}, seed {seed}", args.out / "logs" / f"{arm}-seed-{seed}.log")


@dataclass(frozen=True)
class Finals:
    """What one run made: its final player of each side, the scripted players, the env steps per side of its
    double-oracle best responses and exploiters (beside the learner's)."""

    run_dir: Path
    players: dict[str, Player]  # side -> its newest snapshot (the attacker: of reward method 2)
    scripted: dict[str, list[Player]]  # side -> its scripted players
    extra_steps: dict[str, int]  # side -> env steps its double-oracle best responses and exploiters trained

    @classmethod
    def of(cls, run_dir: Path) -> "Finals":
        _, store = open_run(run_dir)
        try:
            players = store.players()
        finally:
            store.close()
        def of_kind(side: str, kind: str) -> list[Player]:
            return [p for p in players if p.side == side and p.kind == kind]

        return cls(run_dir, {side: max(of_kind(side, "snapshot"), key=lambda p: p.version) for side in SIDES},
                   {side: of_kind(side, "scripted") for side in SIDES},
                   {side: sum(p.env_steps for p in of_kind(side, "oracle") + of_kind(side, "exploiter")) for side in SIDES})


def win_cell(wins: int, games: int) -> str:
    low, high = wilson_interval(wins, games)
    return f"{wins / games:.3f} [{low:.2f}, {high:.2f}]"


def against_scripted(finals: Finals, episodes: int) -> dict[str, dict[str, list[str]]]:
    """Per side, the win rate cells of its final player and of its Nash mixture (``nash-SIDE``) against each scripted
    player of the other side, on the test games (played and recorded in the run's store where missing). The
    mixture's: its win rate in expectation over the member it draws, each member's rate by its weight."""
    run, store = open_run(finals.run_dir)
    try:
        mixtures = {side: store_mixture(store, f"nash-{side}") for side in SIDES}
        pairs = {(side, name): [(p, o) if side == "attacker" else (o, p) for o in finals.scripted[other_side(side)]]
                 for side in SIDES for name, p in [("final", finals.players[side]), *((m.name, m) for m in mixtures[side].members)]}
        stats = test_game_stats(store, run, finals.run_dir, [pair for side_pairs in pairs.values() for pair in side_pairs], episodes)
    finally:
        store.close()

    def wins(side: str, name: str) -> list[int]:
        return [wins_of(side, stats[a.id, t.id].attacker_wins, episodes) for a, t in pairs[side, name]]

    cells = {}
    for side in SIDES:
        mixture = mixtures[side]
        expected = sum(w * np.array(wins(side, m.name)) / episodes for m, w in zip(mixture.members, mixture.weights))
        cells[side] = {"final": [win_cell(w, episodes) for w in wins(side, "final")],
                       "nash": [f"{rate:.3f}" for rate in expected],
                       "members": [f"{m.name} {w:.2f}" for m, w in zip(mixture.members, mixture.weights)]}
    return cells


def cross_play(finals: dict[str, Finals], game, episodes: int) -> dict[tuple[str, str], int]:
    """Attacker wins of each arm's final attacker against each arm's final team (one training seed), on the test games."""
    positions = evaluation_scenarios(game.scenario, episodes, "test")
    return {(x, y): int(play_fixed_games(game, positions, {
        **policies_of(finals[x].players["attacker"], finals[x].run_dir),
        **policies_of(finals[y].players["team"], finals[y].run_dir),
    }).attacker_wins.sum()) for x in finals for y in finals}


def exploited_in(run_dir: Path, name: str, side: str, args) -> Exploited:
    """``args.br_seeds`` best responses against ``name`` of ``side`` (a team's budget against an attacker), kept or new."""
    if side == "team":
        return exploited(run_dir, name, args.br_env_steps, args.br_seeds, args.episodes)
    starts = {"scratch": [False], "prior": [True], "both": [False, True]}[args.team_br_start]
    trained = [exploited(run_dir, name, args.team_br_env_steps, args.br_seeds, args.episodes, from_prior) for from_prior in starts]
    return max(trained, key=lambda e: e.dev_rate)  # the stronger start, chosen off the test games


def start_shown(found: Exploited, side: str, args) -> list[str]:
    """The page's cells of ``found``: with both starts for a team's best responses, its rate says which counted."""
    cells = found.cells()
    if side == "attacker" and args.team_br_start == "both":
        cells[0] += " (prior)" if found.from_prior else " (scratch)"
    return cells


def over_seeds(values: dict[str, dict[int, float]], arm: str, seeds: list[int], arms: list[str]) -> list[str]:
    """An arm's mean over training seeds with its Student-t interval, and its paired t-test against ``REFERENCE_ARM``."""
    mine = [values[arm][s] for s in seeds]
    interval = "[{:.3f}, {:.3f}]".format(*mean_interval(mine)) if len(seeds) > 1 else "(one seed)"
    if arm == REFERENCE_ARM or REFERENCE_ARM not in arms:
        paired = "-"
    else:
        differences = [values[arm][s] - values[REFERENCE_ARM][s] for s in seeds]
        paired = f"{np.mean(differences):+.3f}" + (f", p = {paired_t_test(differences):.3f}" if len(seeds) > 1 else "")
    return [f"{np.mean(mine):.3f} {interval}", paired]


def main(argv: list[str] | None = None) -> int:
    parser = command_parser(prog="python bench/league_quality.py", description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("runs/league_quality"))
    parser.add_argument("--config", default="selfplay_league", help="the config every arm starts from (default selfplay_league)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="an override for every run of every arm (the arms' own overrides win)")
    parser.add_argument("--arms", nargs="+", default=list(ARMS), choices=ARMS)
    parser.add_argument("--seeds", type=count(0), nargs="+", default=[10, 11, 12, 13, 14], help="training seeds")
    parser.add_argument("--tuning-seeds", type=count(0), nargs="*", default=[0, 1, 2],
                        help="the seeds that chose the config's settings (printed; refused among --seeds)")
    parser.add_argument("--phases", type=count(2), default=6, help="alternating phases (even: both sides the same budget)")
    parser.add_argument("--phase-env-steps", type=count(1), default=200_000)
    parser.add_argument("--do-env-steps", type=count(1), default=100_000,
                        help="each double-oracle best response's env steps (league-do arms; on top of the learners')")
    parser.add_argument("--terminal-reward", type=float, default=30.0)
    parser.add_argument("--br-env-steps", type=count(1), default=200_000, help="each best response's training budget")
    parser.add_argument("--team-br-env-steps", type=count(1), help="a team's best response's budget (default: --br-env-steps)")
    parser.add_argument("--team-br-start", choices=("both", "prior", "scratch"), default="both",
                        help="a team's best responses start from scratch and from the run's team prior, the stronger on "
                        "the dev games counting (default both), or from one of them")
    parser.add_argument("--br-seeds", type=count(1), default=2, help="best responses per exploited player (default 2)")
    parser.add_argument("--episodes", type=count(1), default=1000, help="test games per pair (default 1000)")
    parser.add_argument("--sides", nargs="+", default=list(SIDES), choices=SIDES, help="whose exploitability to measure")
    parser.add_argument("--jobs", type=count(1), help="runs trained side by side (default: 1; with --address: as many as "
                        "the cluster's CPUs hold), and runs whose best responses train side by side here (default: 1)")
    parser.add_argument("--address", help="train the runs as Tune trials on this Ray cluster (OUT on shared storage)")
    parser.add_argument("--cpus-per-run", type=float, default=2.0, help="CPUs Ray reserves per run (default 2)")
    args = parser.parse_args(argv)
    args.team_br_env_steps = args.team_br_env_steps or args.br_env_steps
    args.seeds = list(dict.fromkeys(args.seeds))  # a seed named twice is one run, counted once over seeds
    if args.phases % 2 or args.cpus_per_run <= 0:
        parser.error("--phases must be even (both sides the same budget) and --cpus-per-run positive")
    chosen = tuning_seeds_error(args.seeds, args.tuning_seeds)
    if chosen:
        print(f"error: {chosen}", file=sys.stderr)
        return 2
    try:
        for arm in args.arms:
            load_config(args.config, arm_overrides(arm, args, args.seeds[0]))
    except ConfigError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if args.address:
        args.address = cluster_or_exit(args.address)
    torch.set_num_threads(1)  # the test games are played in this process, one pair at a time
    runs = {(arm, seed): training_run(arm, seed, args) for arm in args.arms for seed in args.seeds}
    if code := training_exit_code(list(runs.values()), args.out, args.jobs, args.cpus_per_run, args.address):
        return code
    try:
        page = measure(args, {key: run.run_dir for key, run in runs.items()}, argv if argv is not None else sys.argv[1:],
                       args.out / "league_quality.png")
    except subprocess.CalledProcessError as err:
        print(f"error: {shlex.join(err.cmd)} failed (exit {err.returncode}); run this command again to resume",
              file=sys.stderr)
        return 1
    (args.out / "league_quality.md").write_text(page)
    print(page)
    return 0


def measure(args, run_dirs: dict[tuple[str, int], Path], argv: list[str], figure: Path) -> str:
    """Play and exploit every run's final players (reusing what earlier calls kept); the page, and its ``figure``."""
    finals = {key: Finals.of(run_dir) for key, run_dir in run_dirs.items()}
    game = read_config(run_dirs[args.arms[0], args.seeds[0]]).game  # every arm plays the same game (arm_overrides)
    scripted_cells, crossed, found = {}, {}, {}
    for seed in args.seeds:
        for arm in args.arms:
            print(f"measuring {arm}, seed {seed} on {args.episodes} test games per pair", flush=True)
            scripted_cells[arm, seed] = against_scripted(finals[arm, seed], args.episodes)
        crossed[seed] = cross_play({arm: finals[arm, seed] for arm in args.arms}, game, args.episodes)
    def exploit_run(final: Finals) -> dict[tuple[str, str], Exploited]:
        return {(side, target): exploited_in(final.run_dir, final.players[side].name if target == "final" else f"nash-{side}",
                                             side, args) for side in args.sides for target in TARGETS}

    with ThreadPoolExecutor(max_workers=args.jobs or 1) as pool:  # each best response is a process of its own
        for (arm, seed), of_run in zip(finals, pool.map(exploit_run, finals.values())):
            found.update({(arm, seed, side, target): e for (side, target), e in of_run.items()})
    any_run = finals[args.arms[0], args.seeds[0]]
    per_side = args.phases // 2 * args.phase_env_steps
    team_start = {"both": "scratch and from the run's prior (the stronger on the dev games; its start beside its rate)",
                  "prior": "the run's prior", "scratch": "scratch"}[args.team_br_start]
    lines = [
        "# Does the league make less exploitable players? (bench/league_quality.py)", "",
        f"Arms {', '.join(args.arms)} from `{args.config}`: method-2 attacker, terminal reward +-{args.terminal_reward:g}, "
        f"{per_side:,} env steps per side for each learner in every arm; the double-oracle arms' best responses "
        f"{args.do_env_steps:,} env steps each, one after each phase, and the league arms' exploiters on top (\"+ DO, exploiters\": of that side's). Training seeds "
        f"{' '.join(map(str, args.seeds))} (settings chosen on seeds {' '.join(map(str, args.tuning_seeds)) or 'none named'}). "
        f"Every figure on {args.episodes} held-out test games per pair (Wilson 95% within a seed). Exploitability: "
        f"{args.br_seeds} best response(s) per exploited player, an attacker from scratch for {args.br_env_steps:,} env "
        f"steps against a team, a team from {team_start} for {args.team_br_env_steps:,} against an attacker (`league.exploit --games test`); margin: over the best "
        "league member of the other side (chosen on the dev games); flat: learning curves flat over the last third "
        f"of the budget (else the figure is a lower bound). Over seeds: {SEED_INTERVAL}, paired t-test minus `league`.",
        "", "```", "python bench/league_quality.py " + shlex.join(argv), "```", "",
        f"![Each seed's exploitability per arm, with the arm's mean and interval]({figure.name})",
    ]
    exploitability = {}  # (side, target) -> arm -> seed -> the best responses' mean win rate
    for side in args.sides:
        other = other_side(side)
        titles = [p.name.removeprefix("scripted-") for p in any_run.scripted[other]] + [f"{a}'s {other}" for a in args.arms]
        lines += ["", f"## Final {side}s: their win rate on the test games", "",
                  f"Each run's final {side} (Wilson 95%) and its Nash mixture `nash-{side}` (its members and weights; "
                  "its win rate in expectation over the member it draws: the members' rates by their weights).", "",
                  f"| arm | seed | {side} | " + " | ".join(titles) + " |", "| --- " * (len(titles) + 3) + "|"]
        for (arm, seed), final in finals.items():
            scripted = scripted_cells[arm, seed][side]
            cells = scripted["final"] + [
                win_cell(wins_of(side, crossed[seed][(arm, y) if side == "attacker" else (y, arm)], args.episodes),
                         args.episodes) for y in args.arms]
            lines.append(f"| {arm} | {seed} | {final.players[side].name} | " + " | ".join(cells) + " |")
            lines.append(f"| {arm} | {seed} | nash-{side}: {', '.join(scripted['members'])} | "
                         + " | ".join(scripted["nash"] + ["-"] * len(args.arms)) + " |")
        lines += ["", f"## Exploitability of the final {side}s: best responses' win rate on the test games", "",
                  "| arm | seed | env steps + DO, exploiters | final: win rate | margin (member) | flat | "
                  "Nash mixture: win rate | margin (member) | flat |", "| --- " * 9 + "|"]
        for (arm, seed), final in finals.items():
            steps = f"{final.players[side].env_steps:,} + {final.extra_steps[side]:,}"
            cells = [c for target in TARGETS for c in start_shown(found[arm, seed, side, target], side, args)]
            lines.append(f"| {arm} | {seed} | {steps} | " + " | ".join(cells) + " |")
            print(lines[-1], flush=True)
        values = {target: {arm: {seed: found[arm, seed, side, target].mean for seed in args.seeds} for arm in args.arms}
                  for target in TARGETS}
        exploitability.update({(side, target): values[target] for target in TARGETS})
        lines += ["", f"Over training seeds ({SEED_INTERVAL}; minus `{REFERENCE_ARM}`: the mean of the per-seed "
                  "differences, above 0 more exploitable, and the paired t-test's p):", "",
                  "| arm | final: exploitability | minus league | Nash mixture: exploitability | minus league |",
                  "| --- " * 5 + "|"]
        lines += [f"| {arm} | " + " | ".join(c for target in TARGETS for c in over_seeds(values[target], arm, args.seeds, args.arms))
                  + " |" for arm in args.arms]
    lines += ["", "Training:", ""] + [f"- {arm}, seed {seed}: {speed(d)}" for (arm, seed), d in run_dirs.items()]
    exploitability_figure(exploitability, args.arms, args.seeds, figure)
    return "\n".join(lines) + "\n"


def exploitability_figure(values: dict[tuple[str, str], dict[str, dict[int, float]]], arms: list[str], seeds: list[int],
                          out: Path) -> None:
    """A panel per exploited side and target: each seed's best-response win rate per arm (dots), the arm's mean (bar)
    with its interval over seeds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(values), figsize=(5 * len(values), 3.6), squeeze=False)
    x = np.arange(len(arms))
    for ax, ((side, target), by_arm) in zip(axes[0], values.items()):
        for i, arm in enumerate(arms):
            rates = [by_arm[arm][s] for s in seeds]
            ax.scatter(np.full(len(rates), i), rates, color="0.5", s=12, zorder=3)
            mean = float(np.mean(rates))
            low, high = mean_interval(rates) if len(rates) > 1 else (mean, mean)
            ax.errorbar(i, mean, yerr=[[mean - low], [high - mean]], fmt="_", color="C0", markersize=18, capsize=4)
        ax.set_xticks(x, arms)
        ax.set_ylim(0, 1)
        ax.set_ylabel("best responses' win rate (test games)")
        ax.set_title(f"{'Nash mixture' if target == 'nash' else 'final snapshot'}: {side}")
    fig.suptitle(f"exploitability per arm ({len(seeds)} training seeds; {SEED_INTERVAL})")
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())

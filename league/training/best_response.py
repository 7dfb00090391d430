"""Best responses: a fresh learner trained against one frozen player alone, then evaluated
against it and recorded as a league member (kind ``best_response``).

How it trains, and why:

- **From scratch** by default: the best response's side starts without the run's prior
  (``ppo.attacker_prior`` or ``ppo.team_prior`` set to ``none`` for its side only; the
  frozen player keeps its own, or it would not be the player it is). ``from_prior=True``
  (``league.exploit --from-prior``) keeps the run's prior. Its network is the run's
  (``ppo.hidden``, ``ppo.attacker_heading_cosines``: inputs, not a prior); the player row
  records which start (``from_prior``).
- **Trained as measured**: the frozen player acts by its policy's mean in training
  (``league.frozen_players_explore: false``), as it does in the evaluation that scores the
  best response (a run on ``resources.sampler: standard``, which cannot, trains its best
  responses on ``fast``).
- **Its learning curve**: every ``budget / CURVE_POINTS`` env steps, the best response as it
  is then plays the frozen player on the first ``evaluation.curve_episodes`` fixed games
  (``BestResponseCurves``); ``league.analysis.exploitability.plateau`` reads whether the
  curve is flat at the end of the budget.

Training is the league's own machinery: a one-phase run (``Coordinator`` through
``league.rllib.bridge``) in a scratch directory inside the run directory, removed at the
end, whose only opponent is the frozen player (its saved module loaded into the
algorithm). Each best response then joins the run's league database (parent: the
exploited player; its seed, budget and start recorded) with its module in ``players/`` and its
evaluation results, one transaction per seed; it is not in the league's training pool
nor in its meta-game. What their results say, the player's exploitability and its margin over
the league, is read by ``league.analysis.exploitability``; ``python -m league.exploit`` is the
command. The curve points stay with the scratch run (they are printed, not stored).

**Against a mixture player** (``nash-team``, ``league.core.mixture``): the scratch run holds
every member, and each training episode's opponent is one member drawn with the mixture's
weights from (the iteration's match-plan seed, the episode id): a ``MatchPlan`` whose opponents
are the members. It is evaluated against the mixture (a member drawn per fixed game,
its seed, ``--mixture-seed``). A mixture is no league member, so the best response's row has no parent;
the store's meta entry ``MIXTURE_BEST_RESPONSES`` names the mixture it was trained against,
its seed and its result.

Not to be confused with exploiters (kind ``exploiter``, ``league.exploiters`` in the
config): those train inside the league, against the other side's newest snapshots.
"""

from __future__ import annotations

import shutil
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

from league.analysis.exploitability import (
    MIXTURE_BEST_RESPONSES, Baseline, BestResponseResult, CurvePoint, Exploitability, baseline_of, mixture_best_responses,
    on_test_games,
)
from league.config import RunConfig
from league.core.league import League, Records, Weights
from league.core.match_plan import MatchPlan
from league.core.mixture import Contestant, Mixture
from league.core.payoff import wins_of
from league.core.players import NewPlayer, Player, other_side
from league.core.schedule import PhaseState
from league.state.store import LeagueStore

DEFAULT_ENV_STEPS = 200_000
DEFAULT_SEEDS = 3
# docs/results/learning.md, "Does it learn?": with +-30 at the end of a game the method-2 attacker learned to
# win (0.786 against the scripted team); with 10 it still drifted into interceptions.
TERMINAL_REWARD = 30.0
SCRATCH_PREFIX = ".exploit-"
CURVE_POINTS = 6  # learning-curve points over a best response's budget


def best_response_config(run: RunConfig, exploited: Contestant, seed: int, env_steps: int, from_prior: bool = False) -> RunConfig:
    """The exploited run's config for one phase of the other side learning, seeded, terminal reward on, the
    other side from scratch (unless ``from_prior``), the exploited player acting by its mean, a learning curve."""
    data = run.model_dump(mode="json")
    side = other_side(exploited.side)
    if not data["game"]["terminal_reward"]:
        data["game"]["terminal_reward"] = TERMINAL_REWARD
    if not from_prior:  # the exploited side's prior stays: it is part of the frozen player
        data["ppo"][f"{side}_prior"] = "none"
        if side == "attacker":  # no prior to be pulled back to
            data["ppo"]["attacker_residual_penalty"] = 0.0
    data["name"] = f"{run.name}-best-response"
    data["seed"] = seed
    data["league"]["mode"] = "protocol"
    # One phase of `env_steps`; its opponent is BestResponseTraining's (the exploited player alone).
    data["league"]["phases"] = [{"learner": side, "env_steps": env_steps, "opponents": "scripted"}]
    data["league"]["attacker_reward_methods"] = None  # one attacker: game.attacker_reward
    data["league"]["exploiters"] = []  # the best response trains alone
    data["league"]["exploiter_phases"] = "all"
    data["league"]["double_oracle"] = {"env_steps": 0}  # a best response adds none itself
    # One opponent: nothing to weigh (PSRO's rule would need a meta-game the scratch run has not).
    data["league"]["pfsp"] = "uniform"
    data["league"]["frozen_players_explore"] = False  # trained against the mean actions it is measured against
    if data["resources"]["sampler"] == "standard":  # which cannot play a frozen player's mean
        data["resources"]["sampler"] = "fast"
    data["evaluation"].update(every_iterations=0, workers=0, curve_every_env_steps=max(1, env_steps // CURVE_POINTS))
    data["checkpoint_every"] = 2**31  # only the final checkpoint (the Coordinator makes it when training is done)
    return RunConfig.model_validate(data)


def best_response_curves(base):
    """The learning curves of a best response: against the exploited player alone, no reference rows.

    (Made from ``league.evaluation.learning_curves.LearningCurves`` on first use: it imports torch.)"""
    from league.evaluation.learning_curves import LIVE_MODULES, Measurements
    from league.evaluation.learning_curves import CurvePoint as StoredPoint

    class BestResponseCurves(base):
        def __init__(self, run: RunConfig, run_dir: Path, exploited: Contestant, opponent: Player, log):
            super().__init__(run, run_dir, log)  # run_dir: the exploited player's, where its module is
            self.exploited = exploited
            self.opponent = opponent  # its row in the scratch run (a mixture's first member: the row points need one)

        def measure(self, live_module, store, learners, candidates, steps_before, steps_now) -> Measurements:
            measured = Measurements([], [])
            for learner in self.due(learners, steps_before, steps_now):
                path = Path(LIVE_MODULES, learner.name)
                live = {str(self.run_dir / path): live_module(learner)}
                stats = self.play(replace(learner, checkpoint=str(path)), self.exploited, live)
                measured.points.append(StoredPoint(learner, self.opponent, steps_now[learner.name], stats))
                self.log(self.describe(learner, self.exploited, steps_now[learner.name], stats))
            return measured

    return BestResponseCurves


class AgainstFixed(League):
    """A best response's league: its learner meets the exploited player alone, or a mixture's members,
    each episode's drawn with the mixture's weights (rows in the scratch run)."""

    def __init__(self, run: RunConfig, opponents: list[Player], weights: list[float] | None = None):
        super().__init__(run)
        self.opponents = opponents
        self.weights = weights  # a mixture's; None: PFSP over the one opponent, as any league

    def candidates(self, phase: PhaseState, players: list[Player]) -> list[Player]:
        return list(self.opponents)

    def match_plan(self, phase: PhaseState, records: Records, seed: int) -> tuple[MatchPlan, Weights]:
        if self.weights is None:
            return super().match_plan(phase, records, seed)
        learners = self.in_phase(phase, records.players, "learner")
        plan = MatchPlan([p.modules() for p in learners], [[o.modules() for o in self.opponents]] * len(learners),
                         [list(self.weights)] * len(learners), seed=seed)
        return plan, {p.name: {o.name: w for o, w in zip(self.opponents, self.weights)} for p in learners}


def best_response_training(base):
    """The Coordinator class for one phase against ``opponents`` alone (one player, or a mixture's members).

    (Made from ``league.training.coordinator.Coordinator`` on first use: importing it imports RLlib.)"""

    class BestResponseTraining(base):
        def __init__(self, run: RunConfig, *args, opponents: list[Player], exploited: Contestant, exploited_run_dir: Path,
                     name: str | None = None, **kwargs):
            from league.evaluation.learning_curves import LearningCurves

            weights = list(exploited.weights) if isinstance(exploited, Mixture) else None
            super().__init__(run, *args, league=AgainstFixed(run, opponents, weights), **kwargs)
            self.opponents = opponents  # the exploited player's row in the scratch run, or a mixture's members'
            self.name = name  # what the league will call the best response
            self.curves = best_response_curves(LearningCurves)(
                self.run, exploited_run_dir, exploited, opponents[0], lambda text: self.log(text)
            )

        def snapshot_name(self, snapshot: NewPlayer) -> str:  # its progress names it as the league will, not as its scratch run does
            return self.name or super().snapshot_name(snapshot)

    return BestResponseTraining


def build_best_response(
    run: RunConfig, run_dir: Path, exploited: Contestant, seed: int, env_steps: int, scratch: Path, name: str | None = None,
    from_prior: bool = False,
):
    """The coordinator of a new one-phase run in ``scratch``: a fresh learner of the other side
    against ``exploited`` alone (a learned player with its saved weights), or against a mixture's
    members, one drawn per episode with the mixture's weights."""
    from league.rllib import bridge
    from league.training.coordinator import Coordinator, RunState

    config = best_response_config(run, exploited, seed, env_steps, from_prior)
    side = other_side(exploited.side)
    store = LeagueStore(scratch, create=True)
    with store.transaction():
        learner = store.add_player(
            0, NewPlayer(side, "learner", 0, config.game.attacker_reward if side == "attacker" else None)
        )
        members = exploited.members if isinstance(exploited, Mixture) else (exploited,)
        opponents = [
            store.add_player(0, NewPlayer(
                member.side, member.kind, member.version, member.reward_method,
                scripted_attacker=member.scripted_attacker, scripted_targeter=member.scripted_targeter,
                scripted_defender=member.scripted_defender,
            ))
            for member in members
        ]
    weights = list(exploited.weights) if isinstance(exploited, Mixture) else [1.0]
    plan = MatchPlan([learner.modules()], [[o.modules() for o in opponents]], [weights], seed)
    algo = bridge.build_config(config, store.players(), plan).build_algo()
    for member, opponent in zip(members, opponents):
        if member.kind != "scripted":
            bridge.load_frozen_module(algo, opponent.name, run_dir / member.checkpoint)
    coordinator = best_response_training(Coordinator)(
        config, scratch, store, algo, RunState(phase=PhaseState(index=0, side=side, start_iteration=0)),
        seed=seed, opponents=opponents, exploited=exploited, exploited_run_dir=run_dir, name=name,
    )
    return coordinator


def train_and_install(
    run: RunConfig, run_dir: Path, exploited: Contestant, seed: int, env_steps: int, name: str, from_prior: bool = False,
    stop=None,
) -> tuple[Path, int, list[CurvePoint]]:
    """Train one best response against ``exploited`` in a scratch run inside ``run_dir`` (removed after) and
    install its module as ``players/NAME``: that path, env steps trained, learning curve. ``stop``
    (``StopRequests``) ends it between iterations."""
    scratch = Path(tempfile.mkdtemp(prefix=SCRATCH_PREFIX, dir=run_dir))
    try:
        built = build_best_response(run, run_dir, exploited, seed, env_steps, scratch, name, from_prior)
        module, trained, curve = train_built(built, stop)
        return install(module, run_dir, name), trained, curve
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def train_built(coordinator, stop=None) -> tuple[Path, int, list[CurvePoint]]:
    """Train a best response that ``build_best_response`` built to its budget, then stop its algorithm: its
    saved module, env steps trained, learning curve. ``stop`` (``StopRequests``) ends it between iterations."""
    from league.training.progress import ProgressReporter

    scratch = coordinator.run_dir
    try:
        progress = ProgressReporter(scratch, 1, phase_budgets=coordinator.league.schedule.env_step_budgets())
        try:
            coordinator.train(progress, stop)
        finally:
            progress.close()
        side = coordinator.state.phase.side
        trained = coordinator.store.players(side=side, kind="snapshot")[-1]
        curve = [CurvePoint(row["env_steps"], wins_of(side, row["attacker_wins"], row["games"]), row["games"])
                 for row in coordinator.store.curve_points()]
        return scratch / trained.checkpoint, coordinator.state.env_steps, curve
    finally:
        coordinator.algo.stop()
        coordinator.store.close()


def install(module: Path, run_dir: Path, name: str) -> Path:
    """Copy a best response's module from its scratch run to ``players/NAME`` in one rename; its path."""
    target = run_dir / "players" / name
    partial = target.with_name(name + ".partial")
    for stale in (target, partial):  # left by a call killed before it committed this player
        shutil.rmtree(stale, ignore_errors=True)
    shutil.copytree(module, partial)
    partial.rename(target)
    return target


def next_version(players: list[Player], side: str, reward_method: int | None) -> int:
    versions = [p.version for p in players if p.kind == "best_response" and p.side == side and p.reward_method == reward_method]
    return 1 + max(versions, default=-1)


def next_seeds(players: list[Player], exploited: Contestant, k: int, store: LeagueStore | None = None) -> list[int]:
    """``k`` seeds after every seed already used for a best response against ``exploited`` (a mixture's: from
    ``store``'s ``MIXTURE_BEST_RESPONSES``)."""
    if isinstance(exploited, Mixture):
        used = [r["seed"] for r in (mixture_best_responses(store) if store is not None else []) if r["mixture"] == exploited.name]
    else:
        used = [p.seed for p in players if p.kind == "best_response" and p.parent == exploited.id and p.seed is not None]
    first = 1 + max(used, default=-1)
    return list(range(first, first + k))


@dataclass(frozen=True)
class Budget:
    """How each best response is trained and measured."""

    env_steps: int  # trained for
    episodes: int  # fixed games it is evaluated on against the exploited player
    from_prior: bool = False  # started from the run's prior (else from scratch)
    games: str = "dev"  # which fixed games: the dev games, or the held-out test games (a study's)


def played_on_test_games(baseline: Baseline, run: RunConfig, run_dir: Path, store: LeagueStore, episodes: int) -> Baseline:
    """``baseline`` with its member, chosen on the dev games, measured against the exploited player (a mixture:
    each of its members, by their weights) on the first ``episodes`` held-out test games, played and recorded
    where the store has none: the best of many members on the dev games is a little lucky there, and a margin
    over its dev-game rate would be too small by that luck."""
    from league.evaluation.results import test_game_stats

    member, exploited = baseline.member, baseline.exploited
    if member is not None:
        opponents = exploited.members if isinstance(exploited, Mixture) else (exploited,)
        test_game_stats(store, run, run_dir, [(member, o) if member.side == "attacker" else (o, member) for o in opponents], episodes)
    return on_test_games(baseline, store.newest_evaluation_rows("test"))


def train_best_responses(
    run: RunConfig, run_dir: Path, store: LeagueStore, exploited: Contestant, seeds: list[int], budget: Budget, say=print,
) -> Exploitability:
    """Train, evaluate and record one best response per seed; their results against ``exploited`` (a
    mixture: a member drawn per fixed game from its seed) on the budget's fixed games, with the
    league's baselines (which best responses do not change) and each one's learning curve."""
    env_steps, episodes, from_prior = budget.env_steps, budget.episodes, budget.from_prior
    from league.evaluation.engine import evaluate_pairs
    from league.evaluation.results import EVALUATION_SOURCE
    from league.core.payoff import league_ratings

    evaluated = store.newest_evaluation_rows()
    baseline = baseline_of(exploited, store.players(), evaluated)
    if budget.games == "test":
        baseline = played_on_test_games(baseline, run, run_dir, store, episodes)
    say(baseline.line())
    results = []
    for seed in seeds:
        started = time.perf_counter()
        side = other_side(exploited.side)
        config = best_response_config(run, exploited, seed, env_steps, from_prior)
        reward_method = config.game.attacker_reward if side == "attacker" else None
        version = next_version(store.players(), side, reward_method)
        name = NewPlayer(side, "best_response", version, reward_method).name
        target, trained_steps, curve = train_and_install(run, run_dir, exploited, seed, env_steps, name, from_prior)
        new = NewPlayer(side, "best_response", version, reward_method, parent=None if isinstance(exploited, Mixture) else exploited.id, env_steps=trained_steps,
                        checkpoint=str(target.relative_to(run_dir)), seed=seed, env_step_budget=env_steps, from_prior=from_prior)
        provisional = new.unrecorded()
        pair = (provisional, exploited) if side == "attacker" else (exploited, provisional)
        last = store.last_iteration()
        iteration = last["iteration"] if last else 0
        try:  # a module without its player row is removed: the database and players/ stay in step
            [played] = evaluate_pairs(run.game, run_dir, [pair], episodes, games=budget.games)
            with store.transaction():
                player = store.add_player(iteration, new)
                if isinstance(exploited, Mixture):  # no league result: what it won goes into the meta table
                    store.set_meta(MIXTURE_BEST_RESPONSES, mixture_best_responses(store) + [{
                        "player": player.name, "mixture": exploited.name, "seed": seed, "budget": env_steps,
                        "from_prior": from_prior, "wins": wins_of(side, played.attacker_wins, played.games),
                        "games": played.games, "game_set": budget.games, "mixture_seed": exploited.seed,
                        "iteration": exploited.iteration,
                    }])
                else:
                    # the provisional player's id becomes the new row's
                    rows = [replace(r, attacker=player.id) if r.attacker == provisional.id else replace(r, team=player.id)
                            for r in played.outcome_rows()]
                    store.record_evaluation(iteration, rows, EVALUATION_SOURCE[budget.games])
                    if budget.games == "dev":  # the league's ratings never see the test games
                        store.replace_ratings(iteration, league_ratings(store.counted_results(), [p.id for p in store.players()]))
        except BaseException:
            shutil.rmtree(target, ignore_errors=True)
            raise
        result = BestResponseResult(player, exploited, wins_of(side, played.attacker_wins, played.games), played.games, curve,
                                    budget.games)
        results.append(result)
        say(f"{result.line(baseline)}; {time.perf_counter() - started:.0f} s")
    return Exploitability(exploited, env_steps, results, baseline)

"""PSRO's step in a self-play league (``league.double_oracle``): the league's ``OracleStep`` carried out.

After the iteration that ends a self-play phase (``League.oracle_due``; the coordinator asks
after every iteration, and once more when it starts or resumes):

1. the meta-game's pairs without an evaluation (the phase's new snapshots against the other
   side's frozen players) are played on the fixed games;
2. the other side's meta-strategy in that meta-game is what the best response trains against: its
   Nash mixture, the mixture player ``nash-SIDE@ITERATION`` (``league.analysis.mixtures``), or with
   ``league.double_oracle.meta_solver: regret_matching`` its distribution by regret matching
   against the phase side's best responses (``league.analysis.regret_matching``), ``rm-SIDE@ITERATION``;
3. the best response of the phase's side trains against it for ``league.double_oracle.env_steps``
   env steps (``league.training.best_response``: a one-phase scratch run inside the run
   directory, each episode's opponent a member drawn with the mixture's weights), from the run's
   prior as the league's learners start, seeded from the run's ``ORACLES`` stream. It samples in
   the driver (no env runners of its own): the run's env runners keep their CPUs meanwhile;
4. its module is saved as ``players/NAME`` and added to the algorithm as a frozen module, and
   its row (kind ``oracle``) is committed with the pairs of 1 in one transaction, as a member
   created by the phase-ending iteration. From the next iteration on it is in its side's pool,
   an opponent of the other side's learners, and a member of the meta-game.

The phase-ending iteration's checkpoint was written before the step, without the module: a
run resumed from it adds the modules of the oracles its database holds (``restore_modules``),
or, stopped or killed before the commit, trains the oracle again, the same one (same seed,
same mixture, same start).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from league.analysis.mixtures import league_mixture, regret_matching_mixture
from league.analysis.nash import meta_game_players, missing_pairs
from league.config import RunConfig
from league.core.league import OracleStep
from league.core.payoff import aggregate, league_ratings
from league.core.players import Player
from league.rllib import bridge
from league.training.best_response import train_and_install
from league.training.records import timed

if TYPE_CHECKING:
    from league.training.coordinator import Coordinator
    from league.training.stop import StopRequests


def oracle_run(run: RunConfig) -> RunConfig:
    """The run's config with its games sampled in the driver, as many at once as its env runners play."""
    data = run.model_dump(mode="json")
    resources = data["resources"]
    resources["num_envs_per_env_runner"] *= max(1, resources["num_env_runners"])
    resources["num_env_runners"] = 0
    return RunConfig.model_validate(data)


def carry_out(coordinator: Coordinator, step: OracleStep, stop: StopRequests | None = None) -> Player:
    """Train ``step``'s best response against the other side's meta-strategy and add it to the league; its row."""
    store, run, run_dir, iteration = coordinator.store, coordinator.run, coordinator.run_dir, coordinator.state.iteration
    attackers, teams = meta_game_players(store.players())
    missing = missing_pairs(attackers, teams, aggregate(store.newest_evaluation_rows()))
    played, evaluation_seconds = timed(lambda: coordinator.evaluator.evaluate(missing) if missing else [])
    rows = store.newest_evaluation_rows() + [row for pair in played for row in pair.outcome_rows()]
    if run.league.double_oracle.meta_solver == "regret_matching":
        mixture = regret_matching_mixture(step.exploited_side, store.players(), rows, iteration)
    else:
        mixture = league_mixture(f"nash-{step.exploited_side}@{iteration}", store.players(), rows, iteration)
    member = step.member
    (target, trained, curve), training_seconds = timed(lambda: train_and_install(
        oracle_run(run), run_dir, mixture, step.seed, step.env_steps, member.name, from_prior=True, stop=stop))
    member = replace(member, env_steps=trained, checkpoint=str(target.relative_to(run_dir)))
    bridge.add_frozen_player(coordinator.algo, run, member, target)
    coordinator.set_trainable()
    with store.transaction():
        for pair in played:
            store.record_evaluation(iteration, pair.outcome_rows())
        player = store.add_player(iteration, member)
        store.replace_ratings(iteration, league_ratings(store.counted_results(), [p.id for p in store.players()]))
    coordinator.time_split.evaluation += evaluation_seconds
    coordinator.time_split.training += training_seconds
    last = curve[-1] if curve else None
    against = ", ".join(f"{p.name} {w:.3f}" for p, w in zip(mixture.members, mixture.weights))
    coordinator.log(
        f"double oracle after phase {step.phase + 1}: {player.name} trained {trained} env steps in {training_seconds:.0f} s "
        f"against {mixture.name} ({against})"
        + (f"; won {last.wins}/{last.games} of its last curve point's games against it" if last else "")
    )
    return player


def restore_modules(algo: Any, run: RunConfig, run_dir: Path, players: list[Player]) -> None:
    """Add to a restored algorithm the modules of the oracles that joined after its checkpoint was written."""
    for player in players:
        if player.kind == "oracle" and not bridge.has_module(algo, player.name):
            assert player.checkpoint is not None  # committed with its module saved
            bridge.add_frozen_player(algo, run, player, run_dir / player.checkpoint)


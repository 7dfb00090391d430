"""league.pfsp: nash (PSRO's rule): a learner meets the other side's players in proportion to
their Nash weight in the meta-game of every frozen player, each pair evaluated once, when a
plan first needs it.

One tiny run of three alternating phases trains in this process on a private Ray instance;
every iteration's ``MatchPlan`` is recorded on its way to the env runners.
"""

import io
import sqlite3

import numpy as np
import pytest
import torch

from league.analysis.nash import SUPPORT_THRESHOLD, meta_game, meta_game_players
from league.config import load_config
from league.core.payoff import aggregate
from league.rllib import bridge
from league.state.store import LeagueStore
from league.training import lifecycle
from league.training.progress import ProgressReporter

TINY = """
name: tiny-psro
seed: 3
game: {terminal_reward: 1.0}
ppo: {train_batch_size: 200, minibatch_size: 100, num_epochs: 1, hidden: [16]}
resources: {num_cpus: 2, num_env_runners: 0, num_envs_per_env_runner: 4}
league:
  mode: selfplay
  selfplay_phases: 3
  min_phase_episodes: 100000
  phase_env_steps: 400
  pfsp: nash
evaluation: {episodes: 16, workers: 0, curve_every_env_steps: 0}
"""


@pytest.fixture(scope="module")
def psro_run(ray_instance, tmp_path_factory):
    """The finished run's store, its recorded plans ``(iteration, plan)`` and its directory."""
    torch.set_num_threads(1)
    base = tmp_path_factory.mktemp("psro")
    (base / "tiny.yaml").write_text(TINY)
    run = load_config(str(base / "tiny.yaml"))
    run_dir = base / "run"
    run_dir.mkdir()
    plans, holder = [], {}
    real_set_match_plan = bridge.set_match_plan

    def recording(algo, plan):
        plans.append((holder["coordinator"].state.iteration + 1, plan))
        real_set_match_plan(algo, plan)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(bridge, "set_match_plan", recording)
        store = LeagueStore(run_dir, create=True)
        coordinator = holder["coordinator"] = lifecycle.start(run, run_dir, store)
        coordinator.train(ProgressReporter(run_dir, 3, stream=io.StringIO()))
        coordinator.algo.stop()
    yield store, plans, run_dir
    store.close()


def test_a_learner_meets_the_other_sides_nash_mixture_of_the_frozen_players_then(psro_run):
    store, plans, _ = psro_run
    players = store.players()
    by_modules = {frozenset(p.modules().items()): p for p in players}
    payoff = aggregate(store.newest_evaluation_rows())  # each pair evaluated once (below)
    sides_met = set()
    for iteration, plan in plans:
        attackers, teams = meta_game_players([p for p in players if p.created_iteration < iteration])
        meta = meta_game(attackers, teams, payoff)
        assert meta is not None, f"iteration {iteration}: a pair of frozen players was not evaluated"
        [learner] = [by_modules[frozenset(entry.items())] for entry in plan.learners]
        side_players, mixture = (teams, meta.equilibrium.column_mixture) if learner.side == "attacker" else (
            attackers, meta.equilibrium.row_mixture)
        nash = {p.id: w if w > SUPPORT_THRESHOLD else 0.0 for p, w in zip(side_players, mixture)}
        [opponents], [probabilities] = plan.opponents, plan.probabilities
        met = [by_modules[frozenset(o.items())].id for o in opponents]
        assert sorted(met) == sorted(nash), "the learner's candidates are the other side's frozen players"
        expected = np.array([nash[i] for i in met]) / sum(nash.values())
        np.testing.assert_allclose(probabilities, expected, rtol=0, atol=1e-12)  # float64 sums of a few terms
        sides_met.add(learner.side)
    assert sides_met == {"attacker", "team"}
    assert any(p.kind == "snapshot" and p.version > 0 for p in players if p.created_iteration < plans[-1][0])


def test_each_pair_of_frozen_players_is_evaluated_once_when_first_needed(psro_run):
    store, _, run_dir = psro_run
    with sqlite3.connect(run_dir / "league.db") as db:
        rows = db.execute(
            "SELECT attacker, team, COUNT(DISTINCT iteration), MIN(iteration) FROM matches "
            "WHERE source = 'evaluation' GROUP BY attacker, team"
        ).fetchall()
    created = {p.id: p.created_iteration for p in store.players()}
    assert any(first == 1 for *_, first in rows) and any(first > 1 for *_, first in rows)  # at the start; later snapshots'
    for attacker, team, times, first in rows:
        # once, in the first iteration after both joined the league (a snapshot joins at its phase's end)
        assert (times, first) == (1, max(created[attacker], created[team]) + 1)

"""league.double_oracle (PSRO's step): at each self-play phase's end a best response of the
phase's side, trained against the other side's Nash mixture, joins the pool as a frozen
player (kind ``oracle``) that the next phase's learners meet; a run stopped after the step,
or killed inside it, and resumed is the run never stopped.

Three tiny runs of two phases (attacker, team) train in this process on a private Ray
instance: one uninterrupted, one stopped right after the first oracle committed, one killed
while the first oracle's module was being added (its row not committed); a fourth of three
phases uses ``meta_solver: regret_matching`` with ``pfsp: nash``. Every iteration's
``MatchPlan`` of the uninterrupted runs is recorded on its way to the env runners.
"""

import io
import sqlite3

import numpy as np
import pytest
import torch

from league import run as run_cli
from league.config import load_config
from league.rllib import bridge
from league.state.run_dir import run_differences
from league.state.store import LeagueStore
from league.training import lifecycle, oracle
from league.training.progress import ProgressReporter
from league.training.stop import Stopped

TINY = """
name: tiny-double-oracle
seed: 5
game: {terminal_reward: 1.0}
ppo: {train_batch_size: 200, minibatch_size: 100, num_epochs: 1, hidden: [16]}
resources: {num_cpus: 2, num_env_runners: 0, num_envs_per_env_runner: 8}
league:
  mode: selfplay
  selfplay_phases: 2
  min_phase_episodes: 100000
  phase_env_steps: 800
  double_oracle: {env_steps: 400}
evaluation: {episodes: 8, workers: 0, curve_every_env_steps: 0, curve_episodes: 8}
"""


class Interrupted(Exception):
    """Stands for a SIGKILL: the process ends where it is, nothing more is written."""


def train(run, run_dir, interrupt=None):
    """Train ``run`` into ``run_dir``; with ``interrupt`` (which breaks the new coordinator once, its
    changes made through the ``MonkeyPatch`` it is given), stop where it breaks, resume from the
    newest checkpoint and train to the end. The store."""
    store = LeagueStore(run_dir, create=True)
    coordinator = lifecycle.start(run, run_dir, store)
    progress = ProgressReporter(run_dir, 2, stream=io.StringIO())
    if interrupt is not None:
        with pytest.MonkeyPatch.context() as patch, pytest.raises((Stopped, Interrupted)):
            interrupt(coordinator, patch)
            coordinator.train(progress)
        coordinator.algo.stop()
        store.close()
        store = LeagueStore(run_dir)
        coordinator = lifecycle.resume_run(run_dir, run, store, say=lambda text: None)
    coordinator.train(progress)
    coordinator.algo.stop()
    progress.close()
    return store


@pytest.fixture(scope="module")
def config(tmp_path_factory):
    base = tmp_path_factory.mktemp("double-oracle")
    (base / "tiny.yaml").write_text(TINY)
    return base / "tiny.yaml"


@pytest.fixture(scope="module")
def whole(ray_instance, config):
    """The uninterrupted run: its store, directory and recorded plans ``(iteration, phase, plan)``."""
    torch.set_num_threads(1)
    run = load_config(str(config))
    run_dir = config.parent / "whole"
    run_dir.mkdir()
    plans, holder = [], {}
    real_set_match_plan, real_start = bridge.set_match_plan, lifecycle.start

    def recording(algo, plan):
        main = holder.get("coordinator")
        if main is not None and algo is main.algo:  # (not a best response's scratch run)
            state = main.state
            plans.append((state.iteration + 1, state.phase.index, plan))
        real_set_match_plan(algo, plan)

    def starting(*args, **kwargs):
        holder["coordinator"] = real_start(*args, **kwargs)
        return holder["coordinator"]

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(bridge, "set_match_plan", recording)
        patch.setattr(lifecycle, "start", starting)
        store = train(run, run_dir)
    yield store, run_dir, plans
    store.close()


def test_a_phase_end_adds_a_best_response_that_the_next_phase_meets(whole):
    store, run_dir, plans = whole
    players = store.players()
    oracles = {p.name: p for p in players if p.kind == "oracle"}
    assert sorted(oracles) == ["attacker-m2-oracle-v1", "team-oracle-v1"]  # one after each phase
    first = oracles["attacker-m2-oracle-v1"]
    phase_ends = {row["phase"]: row["iteration"] for row in store.iteration_rows()}  # each phase's last iteration
    assert first.created_iteration == phase_ends[0] and oracles["team-oracle-v1"].created_iteration == phase_ends[1]
    assert first.env_steps >= 400 and first.env_step_budget == 400 and first.from_prior
    assert (run_dir / first.checkpoint / "module_state.pkl").exists()
    assert not list(run_dir.glob(".exploit-*"))  # the scratch runs are gone

    # The team phase's learner meets it with a nonzero probability, and its games are recorded.
    team_plans = [plan for _, phase, plan in plans if phase == 1]
    assert team_plans
    for plan in team_plans:
        [opponents], [probabilities] = plan.opponents, plan.probabilities
        drawn = {o["attacker"]: w for o, w in zip(opponents, probabilities)}
        assert drawn.get(first.name, 0.0) > 0
    with sqlite3.connect(run_dir / "league.db") as db:
        [(games,)] = db.execute(
            "SELECT SUM(count) FROM matches WHERE source = 'training' AND attacker = ?", (first.id,)).fetchall()
    assert games and games > 0
    # It is a member of the meta-game: every pair with the other side's frozen players evaluated (its
    # pairs by the next oracle step, before the team's best response trained against the attackers' mixture).
    teams_then = [p for p in players if p.side == "team" and p.kind in ("snapshot", "scripted")]
    evaluated = {(row.attacker, row.team) for row in store.newest_evaluation_rows()}
    assert {(first.id, t.id) for t in teams_then} <= evaluated


def test_a_run_stopped_after_the_oracle_step_and_resumed_is_the_run_never_stopped(whole, config):
    """Stopped right after the first oracle committed: its row is in the database, the checkpoint
    the resume starts from was written before its module joined the algorithm."""

    def stop_after_the_first_oracle(coordinator, patch):
        def then_stop(*args):
            oracle.carry_out(*args)
            raise Stopped(15)

        patch.setattr(coordinator, "oracle", then_stop)

    run_dir = config.parent / "stopped"
    run_dir.mkdir()
    train(load_config(str(config)), run_dir, stop_after_the_first_oracle).close()
    assert run_differences(whole[1], run_dir) == []


def test_a_run_killed_inside_the_oracle_step_and_resumed_is_the_run_never_killed(whole, config):
    """Killed after the first oracle trained and its module was saved, before its row was committed:
    the resume trains it again, the same one."""

    def kill_before_the_first_oracle_commits(coordinator, patch):
        def killed(*args):
            raise Interrupted

        patch.setattr(bridge, "add_frozen_player", killed)

    run_dir = config.parent / "killed"
    run_dir.mkdir()
    train(load_config(str(config)), run_dir, kill_before_the_first_oracle_commits).close()
    assert run_differences(whole[1], run_dir) == []


@pytest.mark.parametrize("override, named", [
    ("league.double_oracle.env_steps=-1", "league.double_oracle.env_steps"),
    ("league.double_oracle.env_stepz=100", "league.double_oracle.env_stepz"),
    ("league.double_oracle.meta_solver=regret", "league.double_oracle.meta_solver"),
])
def test_a_bad_double_oracle_value_exits_2_naming_the_key(config, tmp_path, capsys, override, named):
    assert run_cli.main(["--config", str(config), "--run-dir", str(tmp_path / "x"), "--set", override]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and named in err, err
    assert not (tmp_path / "x").exists()


def test_regret_matching_needs_the_double_oracles_best_responses(config, tmp_path, capsys):
    overrides = ["--set", "league.double_oracle.env_steps=0", "--set", "league.double_oracle.meta_solver=regret_matching"]
    assert run_cli.main(["--config", str(config), "--run-dir", str(tmp_path / "x"), *overrides]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "league.double_oracle.meta_solver" in err and "env_steps" in err, err


def test_the_double_oracle_step_needs_self_play(config, tmp_path, capsys):
    protocol = ["--set", "league.mode=protocol", "--set", "league.phases=[{learner: attacker, env_steps: 100}]"]
    assert run_cli.main(["--config", str(config), "--run-dir", str(tmp_path / "x"), *protocol]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "league.double_oracle.env_steps" in err and "selfplay" in err, err


def test_with_regret_matching_the_learners_meet_the_distribution_against_the_best_responses(ray_instance, config):
    """``meta_solver: regret_matching`` with ``pfsp: nash``: in each of three phases the learner meets
    the other side with its regret-matching weights against the best responses
    (``league.analysis.regret_matching``): evenly while there is none, not by the meta-game's Nash mixture."""
    from league.analysis.nash import meta_game, meta_game_players, mixture_by_player
    from league.analysis.regret_matching import restricted_distributions
    from league.core.payoff import aggregate

    run = load_config(str(config), ["league.selfplay_phases=3", "league.pfsp=nash",
                                    "league.double_oracle.meta_solver=regret_matching"])
    run_dir = config.parent / "regret-matching"
    run_dir.mkdir()
    plans, holder = [], {}
    real_set_match_plan = bridge.set_match_plan

    def recording(algo, plan):
        main = holder.get("coordinator")
        if main is not None and algo is main.algo:
            plans.append((main.state.iteration + 1, main.state.phase.index, plan))
        real_set_match_plan(algo, plan)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(bridge, "set_match_plan", recording)
        store = LeagueStore(run_dir, create=True)
        holder["coordinator"] = coordinator = lifecycle.start(run, run_dir, store)
        coordinator.train(ProgressReporter(run_dir, 3, stream=io.StringIO()))
        coordinator.algo.stop()
    players = store.players()
    by_modules = {frozenset(p.modules().items()): p for p in players}
    payoff = aggregate(store.newest_evaluation_rows())
    assert {phase for _, phase, _ in plans} == {0, 1, 2}
    for iteration, phase, plan in plans:
        meta = meta_game(*meta_game_players([p for p in players if p.created_iteration < iteration]), payoff)
        expected, nash = restricted_distributions(meta), mixture_by_player(meta)
        met = [by_modules[frozenset(o.items())].id for o in plan.opponents[0]]
        np.testing.assert_allclose(plan.probabilities[0], [expected[i] for i in met], atol=1e-9)
        if phase == 1:  # the teams have no best response yet: the attackers are met evenly, not by Nash
            assert any(p.kind == "oracle" for p in meta.attackers) and not any(p.kind == "oracle" for p in meta.teams)
            assert plan.probabilities[0] == pytest.approx([1 / len(met)] * len(met))
            assert not np.allclose([nash[i] for i in met], plan.probabilities[0], atol=0.01)
        if phase == 2:  # against the attacker's best response of the first phase
            assert any(p.kind == "oracle" for p in meta.attackers)
    store.close()

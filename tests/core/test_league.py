"""The league's decisions from plain records: no store, no Ray."""

import pytest

from league.config import RunConfig
from league.core.league import League, Records
from league.core.payoff import OutcomeCount
from league.core.players import NewPlayer, Player, role_of
from league.core.schedule import PhaseState

RUN = RunConfig.model_validate({
    "name": "x", "checkpoint_every": 10, "evaluation": {"every_iterations": 4},
    "league": {"mode": "selfplay", "selfplay_phases": 2, "exploiters": ["team"], "pfsp": "squared",
               "scripted_attackers": ["lead_intercept"],
               "scripted_teams": [{"targeter": "avoid_attacker", "defender": "pure_pursuit"}]},
})


def rows(members: list[NewPlayer]) -> list[Player]:
    """The members as the store would give them back: ids in order."""
    return [Player(id=i, **m.columns()) for i, m in enumerate(members, 1)]


def test_a_new_league_is_its_learners_the_team_exploiter_and_the_scripted_players_in_order():
    assert [m.name for m in League(RUN).first_members()] == [
        "attacker-m2", "team", "team-exploiter", "scripted-lead_intercept", "scripted-avoid_attacker+pure_pursuit",
    ]


def test_snapshots_number_a_learners_versions_from_0_and_an_exploiters_from_1():
    league = League(RUN)
    players = rows(league.first_members())
    learner, exploiter = players[1], players[2]
    first = league.snapshot(learner, players, env_steps=0)
    assert (first.kind, first.version, first.parent, first.name) == ("snapshot", 0, learner.id, "team-v0")
    assert league.snapshot(exploiter, players, env_steps=5).name == "team-exploiter-v1"
    players.append(Player(id=9, **first.columns()))
    assert league.snapshot(learner, players, env_steps=7).version == 1
    with pytest.raises(ValueError, match="does not train"):
        league.snapshot(players[3], players, env_steps=0)


def test_the_learner_meets_the_pool_by_pfsp_and_the_exploiter_the_newest_snapshots():
    league = League(RUN)
    players = rows(league.first_members() + [  # ids 6, 7, 8
        NewPlayer("team", "snapshot", 0, parent=2), NewPlayer("attacker", "snapshot", 0, 2, parent=1),
        NewPlayer("attacker", "snapshot", 1, 2, parent=1),
    ])
    team_phase = PhaseState(index=1, side="team", start_iteration=3)
    assert [p.name for p in league.candidates(team_phase, players)] == [
        "scripted-lead_intercept", "attacker-m2-v0", "attacker-m2-v1"]
    assert [p.name for p in league.current_opponents("team", players)] == ["attacker-m2-v1"]
    # The team beat attacker-m2-v0 in all its games: squared PFSP gives it no weight, the unplayed ones are even.
    training = [OutcomeCount(7, 2, "terminal_reached", 10)]
    plan, weights = league.match_plan(team_phase, Records(players, training), seed=5)
    assert weights["team"] == {"scripted-lead_intercept": 0.5, "attacker-m2-v0": 0.0, "attacker-m2-v1": 0.5}
    assert [learner["targeter"] for learner in plan.learners] == ["team", "team-exploiter"]
    assert plan.opponents[1] == [{"attacker": "attacker-m2-v1"}] and plan.seed == 5


def test_a_checkpoint_is_due_on_its_period_at_snapshots_at_the_end_and_when_asked_to_stop():
    league = League(RUN)
    assert [league.checkpoint_due(i, 0, False) for i in (9, 10)] == [False, True]
    assert league.checkpoint_due(7, 2, False) and league.checkpoint_due(7, 0, True)
    assert league.checkpoint_due(7, 0, False, stopping=True)
    assert [league.evaluation_due(i) for i in (3, 4)] == [False, True]
    assert league.next_phase(PhaseState(index=1, side="team", start_iteration=3), 8) is None
    assert league.next_phase(PhaseState(index=0, side="attacker", start_iteration=0), 3) == PhaseState(1, "team", 3)


def test_every_kind_of_the_store_has_its_role_and_an_unknown_one_is_an_error():
    assert [role_of(kind).trains for kind in ("learner", "exploiter", "snapshot", "scripted")] == [True, True, False, False]
    with pytest.raises(ValueError, match="unknown kind of player 'mixture'"):
        NewPlayer("team", "mixture", 0)


def test_a_double_oracle_step_is_due_after_each_self_play_phase_until_its_oracle_joined():
    run = RunConfig.model_validate({"name": "x", "seed": 7, "league": {
        "mode": "selfplay", "selfplay_phases": 3, "double_oracle": {"env_steps": 500}}})
    league = League(run)
    players = rows(league.first_members())
    first, second = (PhaseState(index=k, side=side, start_iteration=0) for k, side in ((0, "attacker"), (1, "team")))
    assert league.oracle_due(first, False, players) is None  # the first phase has not ended
    step = league.oracle_due(second, False, players)
    assert (step.phase, step.member.name, step.member.kind, step.exploited_side, step.env_steps) == (
        0, "attacker-m2-oracle-v1", "oracle", "team", 500)
    assert step.member.from_prior and step.member.role.in_pool
    assert step.seed == league.oracle_due(second, False, players).seed  # from the run's seed alone
    assert step.seed != League(run.model_copy(update={"seed": 8})).oracle_due(second, False, players).seed
    joined = players + [Player(id=99, created_iteration=4, **step.member.columns())]
    assert league.oracle_due(second, False, joined) is None
    # The last phase's oracle is due once training is done; the third phase is the attacker's second.
    third = PhaseState(index=2, side="attacker", start_iteration=0)
    assert league.oracle_due(third, False, joined).member.name == "team-oracle-v1"
    team = Player(id=100, **league.oracle_due(third, False, joined).member.columns())
    assert league.oracle_due(third, False, joined + [team]) is None
    assert league.oracle_due(third, True, joined + [team]).member.name == "attacker-m2-oracle-v2"
    assert League(RUN).oracle_due(second, True, players) is None  # league.double_oracle off

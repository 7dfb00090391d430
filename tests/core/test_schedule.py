"""The league's schedules (``league.core.schedule``): who learns, against whom, when a phase ends."""

import pytest

from league.config import RunConfig
from league.core.players import Player
from league.core.schedule import PhaseState, ProtocolSchedule, SelfPlaySchedule, schedule_of

SCRIPTED = [Player("team", "scripted", 0, scripted_targeter="avoid_attacker", scripted_defender="pure_pursuit", id=5)]
SNAPSHOTS = [Player("team", "snapshot", 0, id=6), Player("team", "snapshot", 1, id=7)]


def protocol() -> ProtocolSchedule:
    run = RunConfig(name="p", league={"mode": "protocol", "phases": [
        {"learner": "attacker", "episodes": 100}, {"learner": "team", "episodes": 50, "opponents": "latest"}]})
    schedule = schedule_of(run)
    assert isinstance(schedule, ProtocolSchedule)
    return schedule


def test_protocol_phases_in_order_against_scripted_players_then_the_newest_snapshot():
    schedule = protocol()
    assert schedule.phases == 2 and [schedule.side(i) for i in range(2)] == ["attacker", "team"]
    assert schedule.opponents(0, SCRIPTED, SNAPSHOTS) == SCRIPTED
    assert schedule.opponents(1, SCRIPTED, SNAPSHOTS) == [SNAPSHOTS[-1]]
    with pytest.raises(RuntimeError, match="latest snapshot"):
        schedule.opponents(1, SCRIPTED, [])
    assert not schedule.finished(PhaseState(0, "attacker", 0, episodes=99, learner_wins=99))
    assert schedule.finished(PhaseState(0, "attacker", 0, episodes=100))
    assert schedule.finished(PhaseState(1, "team", 3, episodes=50))


def test_selfplay_alternates_against_the_whole_pool_and_ends_on_wins_or_steps():
    run = RunConfig(name="s", league={"selfplay_phases": 3, "snapshot_win_rate": 0.6, "min_phase_episodes": 200,
                                      "phase_env_steps": 10_000})
    schedule = schedule_of(run)
    assert isinstance(schedule, SelfPlaySchedule)
    assert schedule.phases == 3 and [schedule.side(i) for i in range(3)] == ["attacker", "team", "attacker"]
    assert schedule.opponents(1, SCRIPTED, SNAPSHOTS) == SCRIPTED + SNAPSHOTS
    assert not schedule.finished(PhaseState(0, "attacker", 0, episodes=199, learner_wins=199, env_steps=9_999))
    assert schedule.finished(PhaseState(0, "attacker", 0, episodes=200, learner_wins=120))  # 0.6 of 200
    assert not schedule.finished(PhaseState(0, "attacker", 0, episodes=200, learner_wins=119))
    assert schedule.finished(PhaseState(0, "attacker", 0, episodes=10, learner_wins=0, env_steps=10_000))


def test_the_team_phases_may_have_their_own_budget():
    run = RunConfig(name="s", league={"min_phase_episodes": 10**6, "phase_env_steps": 10_000, "team_phase_env_steps": 25_000})
    schedule = schedule_of(run)
    assert schedule.finished(PhaseState(0, "attacker", 0, env_steps=10_000))
    assert not schedule.finished(PhaseState(1, "team", 0, env_steps=24_999))
    assert schedule.finished(PhaseState(1, "team", 0, env_steps=25_000))


def test_a_protocol_phase_can_meet_the_scripted_players_and_the_newest_snapshot():
    run = RunConfig(name="p", league={"mode": "protocol", "phases": [
        {"learner": "attacker", "env_steps": 100}, {"learner": "team", "env_steps": 50, "opponents": "scripted_and_latest"}]})
    assert schedule_of(run).opponents(1, SCRIPTED, SNAPSHOTS) == SCRIPTED + [SNAPSHOTS[-1]]


def test_a_protocol_phase_can_meet_the_scripted_players_and_every_snapshot():
    run = RunConfig(name="p", league={"mode": "protocol", "phases": [
        {"learner": "attacker", "env_steps": 100}, {"learner": "team", "env_steps": 50, "opponents": "scripted_and_snapshots"}]})
    assert schedule_of(run).opponents(1, SCRIPTED, SNAPSHOTS) == SCRIPTED + SNAPSHOTS


def test_the_first_protocol_phase_cannot_want_snapshots():
    for opponents in ("latest", "scripted_and_latest", "scripted_and_snapshots"):
        with pytest.raises(ValueError, match="first protocol phase"):
            RunConfig(name="p", league={"mode": "protocol", "phases": [{"learner": "team", "env_steps": 5, "opponents": opponents}]})


def test_the_phases_env_step_budgets_are_known_where_no_phase_ends_after_its_episodes():
    mixed = RunConfig(name="p", league={"mode": "protocol", "phases": [
        {"learner": "attacker", "env_steps": 100}, {"learner": "team", "episodes": 50, "opponents": "latest"}]})
    assert schedule_of(mixed).env_step_budgets() is None
    steps = RunConfig(name="p", league={"mode": "protocol", "phases": [
        {"learner": "attacker", "env_steps": 100}, {"learner": "team", "env_steps": 50, "opponents": "latest"}]})
    assert schedule_of(steps).env_step_budgets() == [100, 50]
    # self-play: each phase's most, by its side (a phase that reaches its win rate ends sooner)
    selfplay = RunConfig(name="s", league={"selfplay_phases": 3, "phase_env_steps": 10_000, "team_phase_env_steps": 25_000})
    assert schedule_of(selfplay).env_step_budgets() == [10_000, 25_000, 10_000]

"""The league store (``league.state.store``)."""

from league.core.payoff import OutcomeCount
from league.core.players import NewPlayer
from league.state.store import LeagueStore


def test_rollback_forgets_later_iterations(tmp_path):
    store = LeagueStore(tmp_path, create=True)
    with store.transaction():
        a = store.add_player(0, NewPlayer(side="attacker", kind="scripted", version=0, scripted_attacker="lead_intercept"))
        t = store.add_player(0, NewPlayer(side="team", kind="learner", version=0))
    for iteration in (1, 2, 3):
        with store.transaction():
            store.record_outcomes(iteration, "training", [OutcomeCount(a.id, t.id, "captured", 2)])
            store.record_iteration(iteration, phase=0, learner_side="team", env_steps=iteration, episodes=2 * iteration,
                                   steps_per_second=1.0, wall_seconds=1.0)
            if iteration == 2:
                store.add_player(iteration, NewPlayer(side="team", kind="snapshot", version=1, parent=t.id))
    store.rollback_after(1)
    assert store.iteration_count() == 1
    assert store.outcome_rows() == [OutcomeCount(a.id, t.id, "captured", 2)]
    assert [p.kind for p in store.players()] == ["scripted", "learner"]

"""The paper's Table 1 (``league.studies.table_one``)."""

import yaml

from envs.agents import Outcome
from league.config import RUN_CONFIG_FILE, RunConfig
from league.core.players import NewPlayer
from league.core.payoff import OutcomeCount
from league.state.store import LeagueStore
from league.studies.table_one import attacker_win_rate


def test_reproduce_reads_the_paper_teams_test_games_not_the_dev_games(tmp_path):
    (tmp_path / RUN_CONFIG_FILE).write_text(yaml.safe_dump(RunConfig(name="x").model_dump(mode="json")))
    store = LeagueStore(tmp_path, create=True)
    with store.transaction():
        straight = store.add_player(0, NewPlayer(side="team", kind="scripted", version=0, scripted_targeter="straight",
                                    scripted_defender="pure_pursuit"))
        paper = store.add_player(0, NewPlayer(side="team", kind="scripted", version=0, scripted_targeter="avoid_attacker",
                                 scripted_defender="pure_pursuit"))
        v1 = store.add_player(0, NewPlayer(side="attacker", kind="snapshot", version=1, reward_method=2))
    stats = dict(games=4, attacker_return_1=0.0, attacker_return_2=0.0, attacker_return_3=0.0, targeter_return=0.0,
                 defender_return=0.0, mean_steps=9.0)
    store.record_evaluation(2, [OutcomeCount(v1.id, paper.id, "captured", 1), OutcomeCount(v1.id, paper.id, "terminal_reached", 3)])
    three_of_four = bytes([Outcome.CAPTURED, Outcome.CAPTURED, Outcome.CAPTURED, Outcome.TERMINAL_REACHED])
    store.record_evaluation_stats(2, "test", v1.id, paper.id, {**stats, "attacker_wins": 3}, three_of_four)
    store.record_evaluation_stats(2, "test", v1.id, straight.id, {**stats, "attacker_wins": 4}, bytes([Outcome.CAPTURED] * 4))
    store.close()
    assert attacker_win_rate(tmp_path, 2, episodes=4) == (0.75, 4)

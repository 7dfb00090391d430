"""League players (``league.core.players``)."""

from league.core.players import Player


def test_the_paper_team_is_recognised_by_its_scripted_players():
    paper = Player("team", "scripted", 0, scripted_targeter="avoid_attacker", scripted_defender="pure_pursuit", id=1)
    other = Player("team", "scripted", 0, scripted_targeter="straight", scripted_defender="pure_pursuit", id=2)
    assert paper.is_paper_team and not other.is_paper_team
    assert not Player("team", "snapshot", 1, id=3).is_paper_team

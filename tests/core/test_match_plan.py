"""``MatchPlan``: a match decided once per episode, drawn by the given probabilities."""

import numpy as np

from league.core.match_plan import MatchPlan


class FakeEpisode:
    def __init__(self, id_):
        self.id_ = id_


def test_match_plan_decides_once_per_episode_and_follows_the_probabilities():
    opponents = [{"attacker": "a0"}, {"attacker": "a1"}, {"attacker": "a2"}]
    plan = MatchPlan([{"targeter": "team", "defender": "team"}], [opponents], [[0.6, 0.3, 0.1]], seed=5)
    counts = np.zeros(3)
    for i in range(6000):
        episode = FakeEpisode(f"{i:032x}")
        chosen = plan("attacker", episode)
        assert plan("attacker", episode) == chosen  # asked again: same answer
        assert plan("targeter", episode) == plan("defender", episode) == "team"  # one shared team module
        counts[int(chosen[1])] += 1
    expected = np.array([0.6, 0.3, 0.1]) * 6000
    assert np.all(np.abs(counts - expected) < 4 * np.sqrt(expected))


def test_match_plan_with_several_learners_gives_each_its_own_opponents():
    team_a, team_b = {"targeter": "ta", "defender": "da"}, {"targeter": "tb", "defender": "db"}
    plan = MatchPlan(
        [{"attacker": "attacker-m1"}, {"attacker": "attacker-m3"}], [[team_a, team_b], [team_a, team_b]],
        [[1.0, 0.0], [0.0, 1.0]], seed=2,
    )
    seen = set()
    for i in range(400):
        episode = FakeEpisode(f"e{i}")
        match = (plan("attacker", episode), plan("targeter", episode), plan("defender", episode))
        assert match in {("attacker-m1", "ta", "da"), ("attacker-m3", "tb", "db")}
        seen.add(match[0])
    assert seen == {"attacker-m1", "attacker-m3"}

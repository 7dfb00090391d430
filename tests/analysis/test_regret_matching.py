"""Anytime PSRO's meta-solver: regret matching against the other side's best responses."""

import numpy as np
import pytest

from league.analysis.nash import meta_game, solve_zero_sum
from league.analysis.regret_matching import regret_matching, restricted_distributions
from league.core.players import Player

GAP = 0.005  # ITERATIONS' promise: the worst case within this of the LP's


def worst_case(strategy, payoff):
    return float(np.min(strategy @ payoff))


@pytest.mark.parametrize("seed", [None, *range(5)])
def test_regret_matching_against_a_best_responder_reaches_the_games_value(seed):
    # (None: an unbalanced matching pennies, value 1/3, played mixed)
    payoff = np.array([[1.0, 0.0], [0.0, 0.5]]) if seed is None else np.random.default_rng(seed).uniform(size=(6, 4))
    strategy = regret_matching(payoff)
    assert strategy.sum() == pytest.approx(1.0) and (strategy >= 0).all()
    assert worst_case(strategy, payoff) == pytest.approx(solve_zero_sum(payoff).value, abs=GAP)


def league_of(rates, attacker_kinds, team_kinds):
    attackers = [Player("attacker", kind, k + 1, 2, id=k + 1) for k, kind in enumerate(attacker_kinds)]
    teams = [Player("team", kind, k + 1, id=100 + k) for k, kind in enumerate(team_kinds)]
    payoff = {(a.id, t.id): (round(1000 * rates[i][j]), 1000) for i, a in enumerate(attackers) for j, t in enumerate(teams)}
    return meta_game(attackers, teams, payoff)


def test_a_side_plays_against_the_other_sides_best_responses_only_and_uniformly_without_any():
    meta = league_of([[0.6, 0.1], [0.3, 0.5]], ["snapshot", "snapshot"], ["oracle", "snapshot"])
    weights = restricted_distributions(meta)
    # The attackers' best answer to the team's best response alone: the first attacker, whatever
    # the team snapshot does to it; the attackers have no best response, so the teams play evenly.
    assert [weights[1], weights[2]] == pytest.approx([1.0, 0.0], abs=GAP)
    assert [weights[100], weights[101]] == [0.5, 0.5]


def test_its_worst_case_against_the_best_responses_does_not_fall_as_players_join_where_nashs_does():
    # Before the team snapshot joins, the attackers' Nash mixture and their regret-matching one both
    # play the first attacker: 0.6 against the team's best response. With the snapshot, the Nash
    # mixture turns to the second attacker and wins 0.386 against the best response; regret matching keeps 0.6.
    rates = [[0.6, 0.1], [0.3, 0.5]]
    before = league_of([[0.6], [0.3]], ["snapshot", "snapshot"], ["oracle"])
    after = league_of(rates, ["snapshot", "snapshot"], ["oracle", "snapshot"])
    against_oracle = np.array(rates)[:, 0]
    nash = [meta.equilibrium.row_mixture @ against_oracle for meta in (before, after)]
    assert nash == pytest.approx([0.6, 0.3 + 0.3 * 2 / 7], abs=1e-6)
    anytime = [np.array([restricted_distributions(m)[i] for i in (1, 2)]) @ against_oracle for m in (before, after)]
    assert anytime == pytest.approx([0.6, 0.6], abs=GAP)


@pytest.mark.parametrize("seed", range(3))
def test_on_random_leagues_players_joining_never_lower_the_worst_case_against_the_best_responses(seed):
    rng = np.random.default_rng(seed)
    rates = rng.uniform(size=(6, 6))
    team_kinds = ["oracle", "snapshot", "oracle", "snapshot", "snapshot", "oracle"]
    responses = [j for j, kind in enumerate(team_kinds) if kind == "oracle"]
    worst = []
    for members in range(1, 7):  # attackers and team snapshots join; the best responses stay
        meta = league_of(rates[:members], ["snapshot"] * members, team_kinds)
        strategy = np.array([restricted_distributions(meta)[i + 1] for i in range(members)])
        worst.append(worst_case(strategy, rates[:members][:, responses]))
    assert all(later >= earlier - 2 * GAP for earlier, later in zip(worst, worst[1:])), worst

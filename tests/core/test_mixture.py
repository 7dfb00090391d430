"""league.core.mixture: mixture players' names, and the per-game draw of their members."""

import numpy as np
import pytest
from scipy.stats import chisquare

from league.core.mixture import (
    MODULUS, Mixture, MixtureError, MixtureName, boundaries, draw_keys, member_indices, parse_mixture_name,
)
from league.core.players import Player


def test_mixture_names_and_misspelt_ones():
    assert parse_mixture_name("nash-attacker") == MixtureName("attacker", None)
    assert parse_mixture_name("nash-team@120") == MixtureName("team", 120)
    assert parse_mixture_name("nash-team@120").name == "nash-team@120"
    for bad, named in (("nash-teem", "'nash-teem' is no mixture player"), ("nash-team@x", "integer from 0, got 'x'"),
                       ("nash-team@-1", "got '-1'"), ("nash-attacker@", "got ''"), ("nash", "is no mixture player")):
        with pytest.raises(MixtureError, match=named) as raised:
            parse_mixture_name(bad)
        assert "\n" not in str(raised.value)


def test_member_frequencies_match_the_weights():
    # 200,000 games: each member's frequency is binomial; within 5 standard errors (sqrt(w (1 - w) / n), at most
    # 0.0011 here) of its weight, a bound a correct draw misses with odds of about 1 in 1.7 million per member.
    weights = [5.0, 3.0, 1.5, 0.5]  # unnormalised on purpose: boundaries() normalises
    n = 200_000
    drawn = member_indices(draw_keys(11, 1, np.arange(n)), boundaries(weights))
    frequencies = np.bincount(drawn, minlength=len(weights)) / n
    expected = np.array(weights) / sum(weights)
    assert np.all(np.abs(frequencies - expected) < 5 * np.sqrt(expected * (1 - expected) / n)), frequencies


def test_keys_are_uniform_and_neighbouring_games_independent():
    n = 100_000
    for seed, stream in ((0, 0), (1, 0), (12345, 1)):
        keys = draw_keys(seed, stream, np.arange(n))
        assert keys.min() >= 0 and keys.max() < MODULUS
        assert chisquare(np.bincount(keys * 64 // MODULUS, minlength=64)).pvalue > 1e-4
        # Lag-1 correlation of independent uniforms: standard error 1 / sqrt(n) = 0.003.
        assert abs(np.corrcoef(keys[:-1], keys[1:])[0, 1]) < 0.02
        pairs = (keys[:-1] * 8 // MODULUS) * 8 + keys[1:] * 8 // MODULUS  # consecutive games' joint cells
        assert chisquare(np.bincount(pairs, minlength=64)).pvalue > 1e-4
    # Neighbouring seeds and the two sides' streams draw unrelated sequences.
    a, b, c = (draw_keys(s, t, np.arange(n)) for s, t in ((0, 0), (1, 0), (0, 1)))
    assert abs(np.corrcoef(a, b)[0, 1]) < 0.02 and abs(np.corrcoef(a, c)[0, 1]) < 0.02


def player(version: int) -> Player:
    return Player(id=version + 10, side="team", kind="snapshot", version=version, checkpoint=f"players/team-v{version}")


def test_a_games_member_depends_only_on_the_seed_and_the_games_index():
    mixture = Mixture("nash-team", "team", 4, (player(1), player(2)), (0.5, 0.5), ((0.5, 0.5), (0.5, 0.5)), 0.6)
    whole = mixture.draw(3, np.arange(1000))
    # Slices, in any order, draw what the whole sequence draws at their indices.
    parts = np.concatenate([mixture.draw(3, np.arange(lo, lo + 250)) for lo in (0, 250, 500, 750)])
    np.testing.assert_array_equal(parts, whole)
    order = np.random.default_rng(0).permutation(1000)
    np.testing.assert_array_equal(mixture.draw(3, order), whole[order])
    assert [mixture.member_of(3, g) for g in (0, 999)] == [mixture.members[whole[0]], mixture.members[whole[999]]]
    # Another seed, or the other side's stream, is another sequence (a half of the games differ on average).
    other_seed = mixture.draw(4, np.arange(1000))
    other_side = member_indices(draw_keys(3, 0, np.arange(1000)), boundaries(mixture.weights))
    assert 0.4 < np.mean(other_seed != whole) < 0.6 and 0.4 < np.mean(other_side != whole) < 0.6
    # One member plays every game, whatever the seed.
    alone = Mixture("nash-team", "team", 4, (player(1),), (1.0,), ((1.0, 1.0),), 0.6)
    assert set(alone.draw(99, np.arange(1000)).tolist()) == {0}

"""``bench/paired_studies.py``: two arms' final players, row by row, paired by seed."""

import pytest

from league.studies.beats_scripted import Row
from tests.training.bench_scripts import bench_module


def row(wins: int, reference_wins: int = 500, against: str = "scripted-straight+pure_pursuit") -> Row:
    return Row("attacker-m2-v1", against, "scripted-apollonius", "attacker", (wins, 1000), (reference_wins, 1000), 0.0, 0.0)


def test_a_row_is_the_difference_paired_by_seed_and_a_row_of_other_opponents_is_refused():
    with bench_module("paired_studies") as bench:
        base = [[row(600)], [row(620)], [row(640)]]
        other = [[row(610)], [row(640)], [row(650)]]  # +0.010, +0.020, +0.010 on the three seeds
        line = bench.paired_rows(base, other)[2]
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert cells[:4] == ["attacker", "straight+pure_pursuit", "0.620 (better than apollonius)",
                             "0.633 (better than apollonius)"]
        assert cells[4].startswith("+0.013 [")
        assert 0.01 < float(cells[5]) < 0.1  # t = 0.0133 / (0.00577 / sqrt 3) = 4.0 on 2 degrees of freedom: p = 0.057

        with pytest.raises(ValueError, match="row 0"):
            bench.paired_rows(base, [[row(600, against="scripted-straight+active_defense")]] * 3)
        with pytest.raises(ValueError, match="different players"):
            bench.paired_rows(base, [[row(600), row(600)]] * 3)

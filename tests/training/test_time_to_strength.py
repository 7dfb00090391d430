"""``bench/time_to_strength.py``: the first curve point where each learner's criterion holds, per run."""

import re

from tests.training.bench_scripts import bench_module


def test_each_run_gets_a_line_and_a_folder_that_is_no_run_exits_2_naming_it(tiny_run, tmp_path, capsys):
    with bench_module("time_to_strength") as bench:
        assert bench.main(["--criterion", "league", "--run-dirs", str(tiny_run)]) == 0
        said = capsys.readouterr().out.splitlines()
        # The tiny run's learners: one attacker (method 2) and the team, each found strong or "never".
        assert re.fullmatch(rf"{tiny_run}: attacker-m2 (never|at [\d,]+ env steps of its own); "
                            r"team (never|at [\d,]+ env steps of its own); strong after .* of \d+ s of training iterations",
                            said[0]), said[0]
        assert said[1].startswith("time to criterion: ")

        assert bench.main(["--criterion", "league", "--run-dirs", str(tiny_run), str(tmp_path)]) == 2
        out, err = capsys.readouterr()
        assert out == "" and err == f"error: --run-dirs: {tmp_path} is not a league run directory (no league.db)\n"

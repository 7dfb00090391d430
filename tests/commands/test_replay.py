"""``league.replay --game K``: only a game the run's evaluation plays."""

from league.replay import main

PAIR = ["--attacker", "attacker-m2-v1", "--team", "scripted-avoid_attacker+pure_pursuit"]


def test_a_game_outside_the_runs_evaluation_games_is_refused_naming_the_bound(run_copy, capsys):
    # The tiny run's evaluation plays 10 fixed games (evaluation.episodes: 10): 0 to 9.
    before = sorted(run_copy.iterdir())
    for game in ("10", "100000"):
        assert main(["--run-dir", str(run_copy), *PAIR, "--game", game]) == 2
        err = capsys.readouterr().err
        assert err.splitlines() == [
            f"error: --game {game} is not one of the run's 10 fixed evaluation games: give 0 to 9 (evaluation.episodes)"
        ]
    assert sorted(run_copy.iterdir()) == before

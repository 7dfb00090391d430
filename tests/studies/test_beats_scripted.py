"""The final table of a study: its rows, verdicts and seed statistics, on the held-out test games."""

import pytest

from envs.scenarios import evaluation_scenarios
from envs.start_classes import StartClass, class_counts, classify
from league.core.players import Player
from league.evaluation.learning_curves import GameStats
from league.evaluation.panel import every_scripted_player
from league.state.run_dir import open_run
from league.study import main as study_main
from league.studies.beats_scripted import (
    CLASSES, FinalPlayers, Row, class_table, comparisons, measure_on_test_games, seed_verdict, table,
)


def scripted_attacker(pid, name):
    return Player(id=pid, side="attacker", kind="scripted", version=0, scripted_attacker=name)


def scripted_team(pid, targeter, defender):
    return Player(id=pid, side="team", kind="scripted", version=0, scripted_targeter=targeter, scripted_defender=defender)


LI, PP = scripted_attacker(1, "lead_intercept"), scripted_attacker(2, "pure_pursuit")
PAPER, STRAIGHT = scripted_team(3, "avoid_attacker", "pure_pursuit"), scripted_team(4, "straight", "pure_pursuit")
A0 = Player(id=5, side="attacker", kind="snapshot", version=0, reward_method=2)
A1 = Player(id=6, side="attacker", kind="snapshot", version=1, reward_method=2)
T0 = Player(id=7, side="team", kind="snapshot", version=0)
T1 = Player(id=8, side="team", kind="snapshot", version=1)
# Attacker wins of 100 games per pair: LI beats the paper's team most, PP the straight team;
# the trained team lets every attacker win least.
RATES = {
    (LI, PAPER): 40, (LI, STRAIGHT): 80, (LI, T0): 50, (LI, T1): 10,
    (PP, PAPER): 35, (PP, STRAIGHT): 85, (PP, T0): 50, (PP, T1): 20,
    (A0, PAPER): 40, (A0, STRAIGHT): 80, (A0, T0): 50, (A0, T1): 10,
    (A1, PAPER): 70, (A1, STRAIGHT): 84, (A1, T0): 60, (A1, T1): 15,
}


def stats(wins: int) -> GameStats:
    # Returns made up so that each pair's own returns tell the pairs apart: A's method-2 return
    # per game is wins / 10, T's and D's -wins / 20 each.
    return GameStats(games=100, attacker_wins=wins, attacker_return_1=0.0, attacker_return_2=wins / 10,
                     attacker_return_3=0.0, targeter_return=-wins / 20, defender_return=-wins / 20, mean_steps=50.0)


TABLE = {(a.id, t.id): stats(wins) for (a, t), wins in RATES.items()}


def test_each_trained_player_is_set_beside_the_best_scripted_player_of_its_side():
    final = FinalPlayers.of([LI, PP, PAPER, STRAIGHT, A0, A1, T0, T1])
    assert (final.attackers, final.team, final.first_attackers, final.first_team) == ({2: A1}, T1, {2: A0}, T0)
    rows = {(r.player, r.against): r for r in comparisons(final, TABLE, untrained=False, terminal_reward=10.0)}
    # The attacker against each scripted team, beside the scripted attacker best against it.
    paper = rows[(A1.name, PAPER.name)]
    assert (paper.reference, paper.rate, paper.reference_rate, paper.verdict()) == (LI.name, 0.70, 0.40, "better")
    straight = rows[(A1.name, STRAIGHT.name)]
    assert (straight.reference, straight.verdict()) == (PP.name, "even")  # 0.84 against 0.85
    # The team against each attacker, beside the scripted team that lets it win least.
    li = rows[(T1.name, LI.name)]
    assert (li.reference, li.rate, li.reference_rate, li.gain, li.verdict()) == (PAPER.name, 0.10, 0.40, pytest.approx(0.30), "better")
    assert rows[(T1.name, A1.name)].reference == PAPER.name
    # On the own reward: A's method-2 return plus 10 per win and -10 per loss (the terminal
    # reward); the team's T + D return minus 10 each per A win and plus 10 each per loss.
    assert (paper.own_return, paper.reference_own_return) == (pytest.approx(7.0 + 4.0), pytest.approx(4.0 - 2.0))
    assert (li.own_return, li.reference_own_return) == (pytest.approx(-1.0 + 16.0), pytest.approx(-4.0 + 4.0))
    assert len(rows) == 2 + 3


def test_untrained_rows_compare_with_version_zero_against_every_opponent():
    final = FinalPlayers.of([LI, PP, PAPER, STRAIGHT, A0, A1, T0, T1])
    rows = comparisons(final, TABLE, untrained=True, terminal_reward=10.0)[5:]
    assert {(r.player, r.reference) for r in rows} == {(T1.name, T0.name), (A1.name, A0.name)}
    assert {r.against for r in rows if r.player == T1.name} == {LI.name, PP.name, A1.name, A0.name}
    worse = next(r for r in rows if r.player == A1.name and r.against == T1.name)
    assert (worse.rate, worse.reference_rate, worse.verdict()) == (0.15, 0.10, "even")


def test_over_seeds_the_paired_test_decides():
    assert seed_verdict([0.10, 0.12, 0.09, 0.11, 0.10])[1] == "better"
    assert seed_verdict([-0.10, -0.12, -0.09, -0.11, -0.10])[1] == "worse"
    p, verdict = seed_verdict([0.30, -0.20, 0.25, -0.30, 0.01])
    assert verdict == "even" and p > 0.5
    rows = {s: ([Row("a", "b", "c", "attacker", (50 + s, 100), (40, 100), 3.0 - s, 5.0)], []) for s in range(5)}
    wins, own = table(rows).split("own reward")
    assert "| a | b | 0.500 [" in wins and "**better** |" in wins
    assert "| a | b | 3.0 | 2.0 |" in own and "| 1.0 [" in own and "**worse** |" in own


def test_a_run_is_measured_on_the_test_games_once(run_copy):
    rows, nash = measure_on_test_games(run_copy, 8)
    _, store = open_run(run_copy)
    try:
        names = {p.name for p in store.players()}
        recorded = store.newest_evaluation_rows("test")
    finally:
        store.close()
    assert {f"scripted-{n}" for n in every_scripted_player()} <= names  # the whole panel joined the league
    assert sum(r.count for r in recorded) == 8 * len({(r.attacker, r.team) for r in recorded})
    assert {r.against for r in rows if r.player == "team-v1"} >= {"scripted-evade_defender", "attacker-m2-v1"}
    assert [(n.side, 0.0 <= n.low <= n.high <= 1.0) for n in nash] == [("attacker", True), ("team", True)]
    # By start class: the class rates, weighted by the classes' sizes on these 8 test games, give the overall rate.
    run, _ = open_run(run_copy)
    counts = class_counts(classify(evaluation_scenarios(run.game.scenario, 8, "test"), run.game))
    for r in rows:
        for k, rate in ((0, r.rate), (1, r.reference_rate)):
            by_class = [r.by_class[i][k] for i in range(len(CLASSES))]
            assert sum(counts[c] * (x or 0.0) for c, x in zip(CLASSES, by_class)) == pytest.approx(8 * rate)
    # A second call plays nothing again: the recorded games are reused, the rows the same.
    again, _ = measure_on_test_games(run_copy, 8)
    _, store = open_run(run_copy)
    try:
        assert store.newest_evaluation_rows("test") == recorded
    finally:
        store.close()
    assert again == rows


def test_the_study_refuses_to_report_a_seed_that_chose_its_settings(tmp_path, capsys):
    assert study_main(["--config", "smoke", "--seeds", "0", "1", "5", "--tuning-seeds", "1", "2", "--out", str(tmp_path)]) == 2
    assert "[1]" in capsys.readouterr().err
    assert study_main(["--config", "smoke", "--seeds", "3", "4", "--out", str(tmp_path), "--set", "ppo.lr=fast"]) == 2
    assert "ppo.lr" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())  # nothing trained, nothing written


def test_free_losses_are_what_the_geometry_gave_away():
    by_class = {StartClass.T_RACE: (0.05, 0.01), StartClass.A_CERTAIN: (0.90, 1.0), StartClass.CONTESTED: (0.3, 0.4)}
    ordered = tuple(by_class[c] for c in CLASSES)
    team = Row("team-v1", "a", "scripted-x", "team", (30, 100), (40, 100), 0.0, 0.0, ordered)
    attacker = Row("attacker-m2-v1", "t", "scripted-y", "attacker", (30, 100), (40, 100), 0.0, 0.0, ordered)
    assert team.free_losses == 0.05  # the attacker won 5% of the starts where T could race home
    assert attacker.free_losses == pytest.approx(0.10)  # it lost 10% of the starts the geometry gave it
    assert Row("p", "a", "r", "team", (1, 2), (1, 2), 0.0, 0.0).free_losses is None  # no outcomes at hand
    text = class_table({s: ([team, attacker], []) for s in range(2)})
    assert "| team-v1 | a | 0.050 / 0.010 | 0.900 / 1.000 | 0.300 / 0.400 | 0.050 [0.050, 0.050] |" in text
    assert "| attacker-m2-v1 | t |" in text and "0.100 [0.100, 0.100] |" in text


def test_a_study_does_not_reuse_a_run_of_another_config(tiny_run, tmp_path, capsys):
    import shutil

    from league.studies.runs import check_same_config

    config = tmp_path / "tiny.yaml"
    config.write_text((tiny_run.parent / "tiny.yaml").read_text())
    out = tmp_path / "study"
    shutil.copytree(tiny_run, out / "tiny" / "seed-3")
    check_same_config(str(config), out / "tiny" / "seed-3", ["seed=3"])  # the same config: reused
    args = ["--config", str(config), "--seeds", "3", "4", "--out", str(out), "--set", "ppo.lr=0.01"]
    assert study_main(args) == 2  # seed 3's run had another learning rate
    assert "ppo.lr" in capsys.readouterr().err
    assert not (out / "tiny" / "seed-4").exists()

"""Learning curves: what a point holds, when points are taken, that training stores them and the report draws them."""

import shutil

import pytest

from envs.config import GameConfig
from envs.match import play, scripted_players
from envs.scenarios import evaluation_scenarios
from envs.scripted import PLAYERS
from league.config import RunConfig
from league.curves import main as curves_main
from league.evaluation.learning_curves import GameStats, LearningCurves, read_curves
from league.reports.plots import plot_run
from league.evaluation.engine import agents_of
from league.core.players import Player
from league.state.run_dir import open_run
from league.state.store import LeagueStore

TERMINAL_REWARD = 30.0


@pytest.mark.parametrize("attacker", ["lead_intercept", "pure_pursuit"])
def test_returns_with_a_terminal_reward_follow_from_the_stored_ones_and_the_wins(attacker):
    positions = evaluation_scenarios("default", 300)
    players = scripted_players(attacker, "avoid_attacker", "pure_pursuit")
    stats = GameStats.of(play(GameConfig(terminal_reward=0.0), players, positions))
    with_terminal = play(GameConfig(terminal_reward=TERMINAL_REWARD), players, positions)
    assert 0 < stats.attacker_wins < stats.games  # both kinds of ending occur, so the bonus is tested both ways
    # Means of ~10 to 100 per-step terms of size <= 60 and a bonus of 30: float64 sums agree
    # to ~1e-13; 1e-9 is far above that and far below any one step's reward.
    for method in (1, 2, 3):
        assert stats.attacker_return(method, TERMINAL_REWARD) == pytest.approx(
            with_terminal.attacker_returns[:, method - 1].mean(), abs=1e-9
        )
        assert stats.attacker_return(method) == getattr(stats, f"attacker_return_{method}")
    team = with_terminal.returns[:, 1] + with_terminal.returns[:, 2]
    assert stats.team_return(TERMINAL_REWARD) == pytest.approx(team.mean(), abs=1e-9)
    # The configured method's column of the core's rewards is the same game's method-2 return.
    assert stats.attacker_return_2 == pytest.approx(play(GameConfig(), players, positions).returns[:, 0].mean(), abs=1e-9)
    assert stats.win_rate("attacker") + stats.win_rate("team") == 1.0


def test_a_point_is_due_each_time_a_learner_passes_another_multiple():
    run = RunConfig(name="c", evaluation={"curve_every_env_steps": 1000})
    curves = LearningCurves(run, ".")
    a = Player(id=1, side="attacker", kind="learner", version=0, reward_method=2)
    b = Player(id=2, side="attacker", kind="learner", version=0, reward_method=3)
    assert curves.due([a, b], {"attacker-m2": 900, "attacker-m3": 1000}, {"attacker-m2": 1100, "attacker-m3": 1999}) == [a]
    assert curves.due([a], {}, {"attacker-m2": 3500}) == [a]  # several multiples in one iteration: one point
    assert curves.due([a], {"attacker-m2": 2000}, {"attacker-m2": 2999}) == []
    off = LearningCurves(RunConfig(name="c", evaluation={"curve_every_env_steps": 0}), ".")
    assert off.due([a], {}, {"attacker-m2": 10**6}) == []


def test_training_stored_a_point_per_multiple_with_the_reference_rows(tiny_run):
    run, store = open_run(tiny_run)
    try:
        curves = {(c.learner.name, c.opponent.name): c for c in read_curves(store)}
        players = {p.name: p for p in store.players()}
        learner_steps = {p.name: p.env_steps for p in store.players(kind="learner")}
    finally:
        store.close()
    every, games = run.evaluation.curve_every_env_steps, run.evaluation.curve_episodes
    assert set(curves) == {
        ("attacker-m2", "scripted-avoid_attacker+pure_pursuit"),
        ("team", "scripted-lead_intercept"),
        ("team", "attacker-m2-v1"),  # the newest attacker snapshot the team trained against
    }
    for (learner, _), curve in curves.items():
        # One point per multiple of `every` the learner passed, taken at the iteration that passed
        # it. A learner plays at most `every` (= the batch of 300) env steps per iteration, fewer
        # when games of the previous phase's matches finish first, so each passes one multiple.
        assert [steps // every for steps in curve.env_steps] == list(range(1, learner_steps[learner] // every + 1))
        assert all(s.games == games for s in curve.stats)
        scripted = sorted(name for kind, name, _ in curve.references if kind == "scripted")
        untrained = [name for kind, name, _ in curve.references if kind == "untrained"]
        assert untrained == [f"{learner}-v0"]
        if curve.learner.side == "attacker":
            assert scripted == sorted(f"scripted-{name}" for name in PLAYERS["attacker"])
        else:
            assert len(scripted) == len(PLAYERS["targeter"]) * len(PLAYERS["defender"])  # every scripted team
    # A stored reference is what those players do on the same fixed games now.
    game = run.game.model_copy(update={"terminal_reward": 0.0})
    positions = evaluation_scenarios(game.scenario, games)
    paper_team = curves[("attacker-m2", "scripted-avoid_attacker+pure_pursuit")]
    lead = next(s for _, name, s in paper_team.references if name == "scripted-lead_intercept")
    assert lead == GameStats.of(play(game, scripted_players("lead_intercept", "avoid_attacker", "pure_pursuit"), positions))
    against_snapshot = curves[("team", "attacker-m2-v1")]
    v0 = next(s for kind, _, s in against_snapshot.references if kind == "untrained")
    agents = {**agents_of(players["attacker-m2-v1"], tiny_run), **agents_of(players["team-v0"], tiny_run)}
    assert v0 == GameStats.of(play(game, agents, positions))


def test_rollback_forgets_curve_rows_after_the_checkpoint(tiny_run, tmp_path):
    copy = tmp_path / "run"
    shutil.copytree(tiny_run, copy)
    store = LeagueStore(copy)
    try:
        iterations = sorted({row["iteration"] for row in store.curve_points()})
        assert len(iterations) >= 2
        store.rollback_after(iterations[0])
        assert {row["iteration"] for row in store.curve_points()} == {iterations[0]}
        assert all(row["iteration"] <= iterations[0] for row in store.curve_references())
    finally:
        store.close()


def test_curves_of_a_run_and_of_several_runs_are_drawn(tiny_run, tmp_path, capsys):
    run, store = open_run(tiny_run)
    try:
        assert plot_run(store, run, tmp_path / "one.png")
    finally:
        store.close()
    assert (tmp_path / "one.png").read_bytes()[:4] == b"\x89PNG"
    seeds = []
    for seed in (0, 1):  # the same run twice stands for two seeds of one config
        seeds.append(tmp_path / f"seed{seed}")
        shutil.copytree(tiny_run, seeds[-1])
    assert curves_main(["--run-dirs", *map(str, seeds), "--out", str(tmp_path / "study")]) == 0
    assert (tmp_path / "study" / "curves.png").read_bytes()[:4] == b"\x89PNG"
    table = (tmp_path / "study" / "curves.md").read_text()
    assert "### attacker-m2 vs scripted-avoid_attacker+pure_pursuit" in table and "| seed1 | 600 |" in table
    assert "reference: scripted-lead_intercept" in table and "reference: untrained (version 0)" in table
    assert curves_main(["--run-dirs", str(tmp_path / "nowhere"), "--out", str(tmp_path / "x")]) == 2
    assert "nowhere" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_a_run_without_curves_draws_none(tmp_path):
    store = LeagueStore(tmp_path, create=True)
    try:
        assert read_curves(store) == [] and not plot_run(store, RunConfig(name="none"), tmp_path / "c.png")
    finally:
        store.close()
    assert not (tmp_path / "c.png").exists()


def test_terminal_reward_by_hand():
    stats = GameStats(games=10, attacker_wins=3, attacker_return_1=1.0, attacker_return_2=2.0, attacker_return_3=3.0,
                      targeter_return=-1.0, defender_return=-2.0, mean_steps=11.0)
    # 3 wins and 7 losses: A's mean bonus is 30 * (3 - 7) / 10 = -12; T and D get +12 each.
    assert stats.attacker_return(2, 30.0) == pytest.approx(2.0 - 12.0, abs=1e-12)
    assert stats.team_return(30.0) == pytest.approx(-3.0 + 24.0, abs=1e-12)
    assert stats.win_interval("team") == pytest.approx((0.3968, 0.8922), abs=1e-4)  # Wilson, 7 of 10

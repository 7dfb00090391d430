"""bench/league_quality.py: the arms' configs give each side's learner the same env steps; a tiny study of two
arms trains, exploits the final players and the Nash mixtures on the test games, writes its page, and reuses
everything when run again."""

import argparse
import json
import threading

import pytest

from league.config import load_config
from tests.training.bench_scripts import bench_module, exploit_here

ARGS = argparse.Namespace(terminal_reward=30.0, episodes=100, phases=4, phase_env_steps=50_000, do_env_steps=20_000,
                          overrides=[], config="selfplay_league")


@pytest.fixture(scope="module")
def league_quality():
    with bench_module("league_quality") as module:
        yield module


def side_budgets(run) -> dict[str, int]:
    """Env steps each side's learner is given (a self-play phase ends on its learner's steps)."""
    league = run.league
    if league.mode == "protocol":
        budgets = {"attacker": 0, "team": 0}
        for phase in league.phases:
            budgets[phase.learner] += phase.env_steps
        return budgets
    per_side = league.selfplay_phases // 2 * league.phase_env_steps
    return {"attacker": per_side, "team": per_side}


def test_every_arm_loads_and_gives_both_sides_the_same_learner_budget(league_quality):
    assert league_quality.ARMS == ("protocol", "naive", "league", "league-do", "league-do-rm")
    for arm in league_quality.ARMS:
        run = load_config("selfplay_league", league_quality.arm_overrides(arm, ARGS, 1))
        assert (run.game.attacker_reward, run.game.terminal_reward, run.seed) == (2, 30.0, 1)
        assert run.league.attacker_reward_methods == [2]
        # The league arms keep the config's exploiters (as shipped); the others have none.
        assert run.league.exploiters == (["attacker"] if arm.startswith("league") else []), arm
        assert side_budgets(run) == {"attacker": 100_000, "team": 100_000}, arm
        if run.league.mode == "selfplay":  # phases end on their budget, never on a win rate
            assert run.league.min_phase_episodes > 10**6 and run.league.pfsp == "squared"
        # The double oracle's best responses: only in the league-do arms, on top of the learners' budget.
        oracle = run.league.double_oracle
        assert oracle.env_steps == (20_000 if arm.startswith("league-do") else 0), arm
        assert oracle.meta_solver == ("regret_matching" if arm == "league-do-rm" else "nash"), arm
    naive = load_config("selfplay_league", league_quality.arm_overrides("naive", ARGS, 1)).league.phases
    assert [p.opponents for p in naive] == ["scripted", "latest", "latest", "latest"]


def test_an_arms_training_seeds_differ_only_in_their_seed(league_quality):
    for arm in league_quality.ARMS:
        runs = [load_config("selfplay_league", league_quality.arm_overrides(arm, ARGS, seed)).model_dump() for seed in (0, 1, 2)]
        assert [run.pop("seed") for run in runs] == [0, 1, 2], arm
        assert runs[0] == runs[1] == runs[2], arm


def test_a_tuning_seed_among_the_seeds_is_refused_before_anything_is_written(league_quality, tmp_path, capsys):
    out = tmp_path / "study"
    # (the bad override too: were the seeds not checked first, the config's error would end it before any training)
    assert league_quality.main(["--out", str(out), "--seeds", "1", "2", "--tuning-seeds", "2", "3", "--set", "ppo.lr=fast"]) == 2
    assert "[2]" in capsys.readouterr().err
    assert league_quality.main(["--out", str(out), "--seeds", "5", "--set", "ppo.lr=fast"]) == 2
    assert "ppo.lr" in capsys.readouterr().err
    assert not out.exists()


TINY = """
name: tiny-quality
ppo: {train_batch_size: 300, minibatch_size: 100, num_epochs: 1, hidden: [16]}
resources: {num_cpus: 1, num_env_runners: 0, num_envs_per_env_runner: 4}
evaluation: {workers: 0, every_iterations: 0, curve_every_env_steps: 0, curve_episodes: 8}
"""


def test_a_tiny_study_exploits_finals_and_mixtures_on_the_test_games_and_reuses_all_when_run_again(
        league_quality, ray_instance, tmp_path, capsys, monkeypatch):
    from envs.scenarios import evaluation_scenarios
    from league.evaluation.engine import play_fixed_games, policies_of
    from league.analysis.mixtures import store_mixture
    from league.state.run_dir import open_run

    from league.studies import exploitation

    # In this process (a process each costs the test 10 s), so one at a time: the module's one Ray instance. The
    # runs' threads (--jobs 2) each take a run's best responses; the runs they came from are checked below.
    one_at_a_time, exploiting = threading.Lock(), []

    def exploit_in_turn(argv):
        with one_at_a_time:
            exploiting.append((threading.get_ident(), argv[argv.index("--run-dir") + 1]))
            return exploit_here(argv)

    monkeypatch.setattr(exploitation, "run_exploit", exploit_in_turn)
    (tmp_path / "tiny.yaml").write_text(TINY)
    out = tmp_path / "study"
    argv = ["--config", str(tmp_path / "tiny.yaml"), "--out", str(out), "--arms", "protocol", "league-do",
            "--seeds", "5", "--phases", "2", "--phase-env-steps", "300", "--do-env-steps", "300", "--br-env-steps", "600",
            "--br-seeds", "1", "--episodes", "6", "--sides", "team", "--jobs", "2", "--cpus-per-run", "1"]
    assert league_quality.main(argv) == 0
    said = capsys.readouterr().out
    page = (out / "league_quality.md").read_text()
    threads = {}
    for thread, run_dir in exploiting:
        threads.setdefault(run_dir, set()).add(thread)
    assert len(threads) == 2 and all(len(t) == 1 for t in threads.values())  # a run's best responses in one thread,
    assert len(set.union(*threads.values())) == 2  # the two runs' in two (--jobs 2)
    assert said.endswith(page + "\n") and len(page.splitlines()) < 200
    assert "python bench/league_quality.py " + " ".join(argv) in page
    assert "settings chosen on seeds 0 1 2" in page and "6 held-out test games" in page
    assert "](league_quality.png)" in page and (out / "league_quality.png").stat().st_size > 0  # the page's figure
    lines = page.splitlines()

    for arm in ("protocol", "league-do"):
        run, store = open_run(out / arm / "seed-5")
        try:
            players = {p.name: p for p in store.players()}
            mixture = store_mixture(store, "nash-team")
            tested = store.evaluation_stats("test")
        finally:
            store.close()
        team = players["team-v1"]
        # Its final team against the scripted attacker: on the test games, recorded in its store.
        assert tested[players["scripted-lead_intercept"].id, team.id]["games"] == 6
        # Its Nash mixture's too: each member's test games, its rate in expectation by the members' weights.
        scripted = [p for p in players.values() if p.side == "attacker" and p.kind == "scripted"]
        expected = [sum(w * (1 - tested[a.id, m.id]["attacker_wins"] / 6) for m, w in zip(mixture.members, mixture.weights))
                    for a in scripted]
        members = ", ".join(f"{m.name} {w:.2f}" for m, w in zip(mixture.members, mixture.weights))
        assert f"| {arm} | 5 | nash-team: {members} | " + " | ".join(f"{r:.3f}" for r in expected) + " | - | - |" in lines
        # Exploited twice on the test games, its final snapshot and its side's Nash mixture, one row with both.
        kept = {p.name: json.loads(p.read_text()) for p in (out / arm / "seed-5" / "exploitability").iterdir()}
        assert sorted(kept) == ["nash-team-600-steps-6-test-games.json", "team-v1-600-steps-6-test-games.json"], arm
        cells = []
        for name in ("team-v1", "nash-team"):
            [call] = kept[f"{name}-600-steps-6-test-games.json"]
            assert call["exploited"] == name and call["game_set"] == "test" and call["best_member"]["game_set"] == "test"
            [seed] = call["seeds"]
            assert seed["games"] == 6 and seed["env_steps"] >= 600
            member = call["best_member"]
            cells += [f"{seed['win_rate']:.3f}", f"{seed['win_rate'] - member['win_rate']:+.3f} ({member['player']})",
                      f"{int(seed['curve_verdict'] == 'flat')}/1"]
        # The double oracle's best responses' env steps beside the learner's, not in them.
        oracle = sum(p.env_steps for p in players.values() if p.kind == "oracle" and p.side == "team")
        assert (oracle > 0) == (arm == "league-do")
        assert f"| {arm} | 5 | {team.env_steps:,} + {oracle:,} | " + " | ".join(cells) + " |" in lines
        # Over seeds: one seed, no interval; no league arm to test against.
        assert [line for line in lines if line.startswith(f"| {arm} | ") and "(one seed)" in line] == [
            f"| {arm} | {kept['team-v1-600-steps-6-test-games.json'][0]['seeds'][0]['win_rate']:.3f} (one seed) | - | "
            f"{kept['nash-team-600-steps-6-test-games.json'][0]['seeds'][0]['win_rate']:.3f} (one seed) | - |"]

    # The arms' finals meet on the test games: two scripted players as finals, whose games differ from dev to test.
    finals = league_quality.Finals.of(out / "protocol" / "seed-5")
    scripted = league_quality.Finals(finals.run_dir, {side: finals.scripted[side][0] for side in ("attacker", "team")},
                                     finals.scripted, finals.extra_steps)
    lineup = {**policies_of(scripted.players["attacker"], None), **policies_of(scripted.players["team"], None)}
    by_hand = {games: int(play_fixed_games(run.game, evaluation_scenarios(run.game.scenario, 12, games), lineup)
                          .attacker_wins.sum()) for games in ("dev", "test")}
    assert by_hand["dev"] != by_hand["test"]
    assert league_quality.cross_play({"x": scripted}, run.game, 12) == {("x", "x"): by_hand["test"]}

    # Again: every run, test game and best response reused; the same page.
    kept = {p: p.stat().st_mtime_ns for p in out.rglob("*.json") if "exploitability" in p.parts}
    assert league_quality.main(argv) == 0
    said, progress = capsys.readouterr()
    assert "study: 2 of 2 runs done (2 reused)" in said and "exploiting" not in progress
    assert (out / "league_quality.md").read_text() == page
    assert {p: p.stat().st_mtime_ns for p in kept} == kept


def test_a_teams_best_responses_start_from_scratch_and_from_the_runs_prior_the_stronger_on_the_dev_games_counting(
        league_quality, tmp_path, monkeypatch):
    from league.studies import exploitation

    calls = []

    def exploit(argv):  # league.exploit --json's output, without training: from the prior weaker on the test games,
        calls.append(argv)  # stronger at its curve's last point (the dev games)
        prior = "--from-prior" in argv
        curve = [{"env_steps": 600, "wins": 150 if prior else 100, "games": 200}]
        return {"seeds": [{"win_rate": 0.5 if prior else 0.9, "curve_verdict": "flat", "curve": curve}], "best_member": None}

    monkeypatch.setattr(exploitation, "run_exploit", exploit)
    args = argparse.Namespace(br_env_steps=900, team_br_env_steps=600, br_seeds=1, episodes=6, team_br_start="prior")
    league_quality.exploited_in(tmp_path, "attacker-m2-v1", "attacker", args)  # a team's best response
    league_quality.exploited_in(tmp_path, "team-v1", "team", args)  # an attacker's: from scratch
    args.team_br_start = "scratch"
    league_quality.exploited_in(tmp_path, "attacker-m2-v1", "attacker", args)  # not the one from the prior again
    assert [("--from-prior" in argv, argv[argv.index("--env-steps") + 1]) for argv in calls] == [
        (True, "600"), (False, "900"), (False, "600")]
    assert sorted(p.name for p in (tmp_path / "exploitability").iterdir()) == [
        "attacker-m2-v1-600-steps-6-test-games.json", "attacker-m2-v1-600-steps-from-prior-6-test-games.json",
        "team-v1-900-steps-6-test-games.json"]
    args.team_br_start = "both"  # both kept: nothing trained, the prior's counts (its curve ends higher)
    both = league_quality.exploited_in(tmp_path, "attacker-m2-v1", "attacker", args)
    assert len(calls) == 3 and (both.mean, both.from_prior) == (0.5, True)
    assert league_quality.start_shown(both, "attacker", args)[0] == "0.500 (prior)"

"""Mixture players (nash-attacker, nash-team) in league.evaluate, exploit, replay, export and status.

The tiny run's Nash mixtures are pure (one member each, the team's a scripted one), so most tests
use a copy whose dev-game results are replaced by a 2x2 game with a unique mixed equilibrium
between the trained snapshots (``MIXED_PAYOFF``): the attackers' mixture is attacker-m2-v1 2/3,
attacker-m2-v0 1/3, the teams' team-v1 5/9, team-v0 4/9 (solved by hand below).
"""

import json
import re
import subprocess
from dataclasses import replace
import sys
import textwrap

import numpy as np
import pytest
import torch

from envs.config import GameConfig
from league import evaluate, exploit, export, replay, status
from league.analysis.mixtures import store_mixture
from league.core.mixture import Mixture, MixtureError
from league.core.payoff import OutcomeCount
from league.evaluation.engine import evaluate_pair, load_module
from league.evaluation.results import last_iteration
from league.state.store import LeagueStore
from league.training import best_response

# The attacker's win rate by (attacker, team); scripted rows and columns are dominated.
MIXED_PAYOFF = {("attacker-m2-v0", "team-v0"): 0.8, ("attacker-m2-v0", "team-v1"): 0.2,
                ("attacker-m2-v1", "team-v0"): 0.3, ("attacker-m2-v1", "team-v1"): 0.6}
GAMES = 1000
# By hand: the attacker mixes p on v0 with 0.8 p + 0.3 (1 - p) = 0.2 p + 0.6 (1 - p), p = 1/3; the team q on
# team-v0 with 0.8 q + 0.2 (1 - q) = 0.3 q + 0.6 (1 - q), q = 4/9; the value 0.5 / 3 + 0.3 = 7/15.
ATTACKER_MIXTURE = {"attacker-m2-v1": 2 / 3, "attacker-m2-v0": 1 / 3}
TEAM_MIXTURE = {"team-v1": 5 / 9, "team-v0": 4 / 9}
VALUE = 7 / 15


def players_of(run_dir):
    store = LeagueStore(run_dir)
    try:
        return {p.name: p for p in store.players()}
    finally:
        store.close()


@pytest.fixture(scope="module")
def mixed_run(tiny_run_once, tmp_path_factory):
    """A copy of the tiny run whose dev-game results of every frozen pair are ``MIXED_PAYOFF`` (the
    scripted attacker wins 0.3, the scripted team loses 0.9)."""
    import shutil

    run_dir = tmp_path_factory.mktemp("mixed") / "run"
    shutil.copytree(tiny_run_once, run_dir)
    store = LeagueStore(run_dir)
    by_name = {p.name: p for p in store.players()}
    attackers = ["attacker-m2-v0", "attacker-m2-v1", "scripted-lead_intercept"]
    teams = ["scripted-avoid_attacker+pure_pursuit", "team-v0", "team-v1"]
    rows = []
    for a in attackers:
        for t in teams:
            rate = MIXED_PAYOFF.get((a, t), 0.3 if a.startswith("scripted") else 0.9)
            wins = round(rate * GAMES)
            rows += [OutcomeCount(by_name[a].id, by_name[t].id, "captured", wins),
                     OutcomeCount(by_name[a].id, by_name[t].id, "terminal_reached", GAMES - wins)]
    with store.transaction():
        store.record_evaluation(last_iteration(store), rows)
    store.close()
    return run_dir


def mixture(run_dir, name):
    store = LeagueStore(run_dir)
    try:
        return store_mixture(store, name)
    finally:
        store.close()


def test_the_mixtures_are_the_meta_games_nash_mixtures(mixed_run):
    for name, expected in (("nash-attacker", ATTACKER_MIXTURE), ("nash-team", TEAM_MIXTURE)):
        found = mixture(mixed_run, name)
        assert [p.name for p in found.members] == list(expected)  # heaviest first
        np.testing.assert_allclose(found.weights, list(expected.values()), atol=1e-6)
        for (low, high), weight in zip(found.ranges, expected.values()):  # unique: each range is the weight
            assert abs(low - weight) < 1e-4 and abs(high - weight) < 1e-4
        assert abs(found.value - (VALUE if name == "nash-attacker" else 1 - VALUE)) < 1e-6
        # the final one is the last iteration's
        assert found.iteration == 4 and replace(mixture(mixed_run, f"{name}@4"), name=name) == found
    # Iteration 0's league had the version-0 snapshots and the scripted players only: team-v0 against
    # attacker-m2-v0 (0.8) is the team's best there.
    early = mixture(mixed_run, "nash-team@0")
    assert [p.name for p in early.members] == ["team-v0"] and abs(early.value - 0.2) < 1e-6
    with pytest.raises(MixtureError, match="nash-team@5: the run has no iteration 5 .its iterations: 0 to 4."):
        mixture(mixed_run, "nash-team@5")


def test_a_mixture_plays_each_game_as_its_drawn_member(mixed_run):
    torch.set_num_threads(1)
    players = players_of(mixed_run)
    game, attacker = GameConfig(), players["attacker-m2-v1"]
    team = mixture(mixed_run, "nash-team")
    # A mixture of one member plays exactly as that member: the same outcomes, steps and returns, game for game.
    alone = Mixture("nash-team", "team", 4, (players["team-v1"],), (1.0,), ((1.0, 1.0),), 0.5)
    as_mixture = evaluate_pair(game, attacker, replace(alone, seed=5), 12, mixed_run)
    as_member = evaluate_pair(game, attacker, players["team-v1"], 12, mixed_run)
    np.testing.assert_array_equal(as_mixture.result.outcome, as_member.result.outcome)
    np.testing.assert_array_equal(as_mixture.result.steps, as_member.result.steps)
    np.testing.assert_array_equal(as_mixture.result.returns, as_member.result.returns)
    # Two members, games 3 to 14: each game is the one its drawn member plays alone (the draw of the game's own
    # index, not of its place in the slice).
    mixed = evaluate_pair(game, attacker, replace(team, seed=5), 12, mixed_run, start=3)
    drawn = [team.member_of(5, g).name for g in range(3, 15)]
    assert mixed.members == {"team": drawn} and len(set(drawn)) == 2
    alone_games = {name: evaluate_pair(game, attacker, players[name], 12, mixed_run, start=3) for name in set(drawn)}
    for k, name in enumerate(drawn):
        assert mixed.result.outcome[k] == alone_games[name].result.outcome[k]
        assert mixed.result.steps[k] == alone_games[name].result.steps[k]


def one_line_error(capsys, named):
    err = capsys.readouterr().err
    assert err.startswith("error:") and named in err and err.count("\n") == 1, err


BAD_NAMES = [("nash-teem", "'nash-teem' is no mixture player"), ("nash-team@99", "no iteration 99")]


def test_evaluate_plays_mixtures_and_records_none_of_their_games(mixed_run, tmp_path, capsys):
    import shutil

    run_dir = tmp_path / "run"
    shutil.copytree(mixed_run, run_dir)
    store = LeagueStore(run_dir)
    before = store.newest_evaluation_rows()
    store.close()
    args = ["--run-dir", str(run_dir), "--workers", "0", "--episodes", "12", "--mixture-seed", "5", "--json"]
    assert evaluate.main(args + ["--players", "nash-attacker", "nash-team", "team-v1"]) == 0
    out = json.loads(capsys.readouterr().out)
    pairs = {(p["attacker"], p["team"]): p for p in out["pairs"]}
    assert set(pairs) == {("nash-attacker", "nash-team"), ("nash-attacker", "team-v1")}
    for pair in pairs.values():
        low, high = pair["interval_95"]
        assert pair["games"] == 12 and low <= pair["attacker_win_rate"] <= high
    # Each mixture's member games: the draws of games 0 to 11 with seed 5 (the attackers' in both pairs).
    shown = {m["mixture"]: m for m in out["mixtures"]}
    attackers, teams = mixture(run_dir, "nash-attacker"), mixture(run_dir, "nash-team")
    for m, pairs_played in ((attackers, 2), (teams, 1)):
        drawn = [m.member_of(5, g).name for g in range(12)]
        assert shown[m.name]["member_games"] == {p.name: pairs_played * drawn.count(p.name) for p in m.members}
    store = LeagueStore(run_dir)
    assert store.newest_evaluation_rows() == before  # nothing recorded: no frozen pair was played, no mixture is one
    store.close()
    for bad, named in BAD_NAMES:
        assert evaluate.main(["--run-dir", str(run_dir), "--players", bad, "team-v1"]) == 2
        one_line_error(capsys, named)


WITHOUT_RAY = textwrap.dedent(
    """
    import json, sys
    import numpy as np
    import torch
    fmt, model, obs_file, out_file = sys.argv[1:]
    obs = np.load(obs_file)
    seeds = np.array([7] * 200 + [8] * 200, dtype=np.int64)
    games = np.concatenate([np.arange(200), np.arange(200)]).astype(np.int64)
    if fmt == "onnx":
        import onnx, onnxruntime
        meta = json.loads({p.key: p.value for p in onnx.load(model).metadata_props}["metadata.json"])
        session = onnxruntime.InferenceSession(model)
        run = lambda: session.run(None, {"observation": obs, "seed": seeds, "game": games})
    else:
        extra = {"metadata.json": ""}
        if fmt == "export":
            policy = torch.export.load(model, extra_files=extra).module()
        else:
            policy = torch.jit.load(model, _extra_files=extra)
        meta = json.loads(extra["metadata.json"])
        def run():
            with torch.no_grad():
                action, member = policy(torch.from_numpy(obs), torch.from_numpy(seeds), torch.from_numpy(games))
            return action.numpy(), member.numpy()
    first, again = run(), run()
    assert "ray" not in sys.modules, "ray was imported"
    np.savez(out_file, action=first[0], member=first[1], member_again=again[1])
    print(json.dumps(meta))
    """
)


@pytest.mark.parametrize("fmt, suffix", [("export", "pt2"), ("torchscript", "pt"), ("onnx", "onnx")])
def test_an_exported_mixture_draws_the_evaluations_members_without_ray(mixed_run, tmp_path, fmt, suffix):
    torch.set_num_threads(1)
    out = tmp_path / f"mixture.{suffix}"
    assert export.main(["--run-dir", str(mixed_run), "--player", "nash-attacker", "--format", fmt, "--out", str(out)]) == 0
    attackers = mixture(mixed_run, "nash-attacker")
    modules = [load_module(mixed_run / p.checkpoint) for p in attackers.members]
    obs = np.random.default_rng(0).normal(size=(400, modules[0].actor_inputs)).astype(np.float32)
    np.save(tmp_path / "obs.npy", obs)
    proc = subprocess.run(
        [sys.executable, "-c", WITHOUT_RAY, fmt, str(out), str(tmp_path / "obs.npy"), str(tmp_path / "out.npz")],
        capture_output=True, text=True, cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    meta = json.loads(proc.stdout.strip().splitlines()[-1])
    assert meta["player"] == {"name": "nash-attacker", "side": "attacker", "mixture": True}
    assert [m["player"] for m in meta["mixture"]["members"]] == list(ATTACKER_MIXTURE)
    found = np.load(tmp_path / "out.npz")
    # The same seed, the same members; the members league.evaluate --mixture-seed draws for those games.
    np.testing.assert_array_equal(found["member"], found["member_again"])
    expected = np.concatenate([attackers.draw(7, np.arange(200)), attackers.draw(8, np.arange(200))])
    np.testing.assert_array_equal(found["member"], expected)
    assert set(expected[:200].tolist()) == {0, 1} and (expected[:200] != expected[200:]).any()
    # Each row's action is its member's deterministic action.
    with torch.no_grad():
        padded = torch.from_numpy(np.concatenate((obs, np.zeros((len(obs), 22), np.float32)), axis=1))
        actions = np.stack([m.deterministic_action(padded).numpy() for m in modules])
    assert np.abs(found["action"] - actions[expected, np.arange(len(obs))]).max() < 1e-5


def test_an_exported_team_mixture_draws_the_teams_members(mixed_run, tmp_path):
    # The team side's draw is a stream of its own (the attackers' is stream 0): the export must use it too.
    out = tmp_path / "team.pt"
    assert export.main(["--run-dir", str(mixed_run), "--player", "nash-team", "--format", "torchscript", "--out", str(out)]) == 0
    teams = mixture(mixed_run, "nash-team")
    games = torch.arange(300)
    members = torch.jit.load(str(out)).member(torch.full((300,), 7), games).numpy()
    np.testing.assert_array_equal(members, teams.draw(7, games.numpy()))


def test_the_docs_mixture_example_runs(mixed_run, tmp_path):
    """The mixture export example of docs/evaluation.md, as written, with the team mixture of a run."""
    from pathlib import Path

    out = tmp_path / "team.pt"
    assert export.main(["--run-dir", str(mixed_run), "--player", "nash-team", "--format", "torchscript", "--out", str(out)]) == 0
    docs = (Path(__file__).resolve().parents[2] / "docs" / "evaluation.md").read_text()
    block = docs.split("<!-- mixture-export-example -->", 1)[1].split("```python", 1)[1].split("```", 1)[0]
    proc = subprocess.run([sys.executable, "-c", block], capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_export_refuses_scripted_members_and_bad_names(tiny_run, mixed_run, tmp_path, capsys):
    out = tmp_path / "team.pt"
    # The tiny run's team mixture is its scripted team alone.
    assert export.main(["--run-dir", str(tiny_run), "--player", "nash-team", "--out", str(out)]) == 2
    one_line_error(capsys, "nash-team has scripted members (scripted-avoid_attacker+pure_pursuit)")
    for bad, named in BAD_NAMES:
        assert export.main(["--run-dir", str(mixed_run), "--player", bad, "--out", str(out)]) == 2
        one_line_error(capsys, named)
    assert not out.exists()


def test_replay_names_the_member_drawn_for_the_game(mixed_run, tmp_path, capsys):
    torch.set_num_threads(1)
    page = tmp_path / "replay.html"
    args = ["--run-dir", str(mixed_run), "--attacker", "nash-attacker", "--team", "team-v1", "--game", "3"]
    assert replay.main(args + ["--mixture-seed", "9", "--out", str(page)]) == 0
    member = mixture(mixed_run, "nash-attacker").member_of(9, 3)
    out = capsys.readouterr().out
    assert f"nash-attacker drew {member.name} (weight" in out and f"{member.name} vs team-v1 (game 3)" in out
    assert page.exists() and page.with_suffix(".png").exists() and member.name in page.read_text()
    for bad, named in [*BAD_NAMES, ("nash-team", "nash-team is a mixture of teams, not of attackers")]:
        assert replay.main(["--run-dir", str(mixed_run), "--attacker", bad, "--team", "team-v1"]) == 2
        one_line_error(capsys, named)


def test_status_shows_each_mixtures_members_weights_and_ranges(mixed_run, capsys):
    assert status.main(["--run-dir", str(mixed_run)]) == 0
    shown = capsys.readouterr().out
    assert "mixture players" in shown
    for name, members in (("nash-attacker", ATTACKER_MIXTURE), ("nash-team", TEAM_MIXTURE)):
        for member, weight in members.items():
            assert re.search(rf"│ {name} +│ {member} +│ +{weight:.3f} │ +{weight:.3f} to {weight:.3f} │", shown), member
    assert status.main(["--run-dir", str(mixed_run), "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)["mixtures"]
    assert [m["mixture"] for m in shown] == ["nash-attacker", "nash-team"]
    assert {m["player"]: round(m["weight"], 6) for m in shown[1]["members"]} == {k: round(v, 6) for k, v in TEAM_MIXTURE.items()}


def test_a_best_response_to_a_mixture_meets_a_member_drawn_per_episode(ray_instance, mixed_run, tmp_path):
    from league.state.run_dir import open_run

    run, store = open_run(mixed_run)
    teams = store_mixture(store, "nash-team")
    store.close()
    coordinator = best_response.build_best_response(run, mixed_run, teams, 0, 600, tmp_path)
    try:
        for member in teams.members:  # each member plays its saved weights
            saved = load_module(mixed_run / member.checkpoint).get_state()
            state = coordinator.algo.get_module(member.name).get_state()
            assert all(np.array_equal(state[key], saved[key]) for key in saved)
        plan, weights = coordinator.league.match_plan(coordinator.state.phase, coordinator.records([]), seed=0)
        assert plan.opponents == [[p.modules() for p in teams.members]] and plan.probabilities == [list(teams.weights)]
        # The plan draws a member per episode, fixed by the episode's id, in the mixture's proportions
        # (4,000 episodes: within 5 standard errors, 0.039, of 5/9).
        drawn = [plan.match(f"episode-{k}")["targeter"] for k in range(4000)]
        assert drawn == [plan.match(f"episode-{k}")["targeter"] for k in range(4000)]
        assert abs(drawn.count("team-v1") / 4000 - TEAM_MIXTURE["team-v1"]) < 0.039
        assert weights == {"attacker-m2": dict(zip([p.name for p in teams.members], teams.weights))}
    finally:
        coordinator.algo.stop()
        coordinator.store.close()


def test_exploit_trains_a_best_response_against_a_mixture(ray_instance, mixed_run, tmp_path, capsys):
    import shutil

    run_dir = tmp_path / "run"
    shutil.copytree(mixed_run, run_dir)
    args = ["--run-dir", str(run_dir), "--env-steps", "600", "--episodes", "10", "--seeds", "1", "--player"]
    assert exploit.main(args + ["nash-team", "--json"]) == 0
    found = json.loads(capsys.readouterr().out)
    assert found["exploited"] == "nash-team" and found["seeds"][0]["games"] == 10
    assert abs(found["meta_game_value"]["value"] - VALUE) < 1e-6  # the attackers' value against the team mixture
    store = LeagueStore(run_dir)
    try:
        [record] = best_response.mixture_best_responses(store)
        br = {p.name: p for p in store.players()}[record["player"]]
        assert (br.kind, br.side, br.parent, br.seed) == ("best_response", "attacker", None, 0)
        assert (record["mixture"], record["games"], record["wins"]) == ("nash-team", 10, found["seeds"][0]["wins"])
        assert record["iteration"] == 4  # the mixture it was: nash-team@4, whatever nash-team becomes if the run goes on
        # A second call takes the next seed against that mixture.
        assert best_response.next_seeds(store.players(), store_mixture(store, "nash-team"), 2, store) == [1, 2]
    finally:
        store.close()
    # league.status reads it back from the store: the same result against the same mixture.
    assert status.main(["--run-dir", str(run_dir), "--json"]) == 0
    [shown] = json.loads(capsys.readouterr().out)["exploitability"]
    assert (shown["exploited"], shown["game_set"], shown["seeds"][0]["wins"]) == ("nash-team", "dev", found["seeds"][0]["wins"])
    assert shown["best_member"] == found["best_member"]
    for bad, named in BAD_NAMES:
        assert exploit.main(args + [bad]) == 2
        one_line_error(capsys, named)


def test_status_and_report_show_the_mixtures_exploitability_on_the_test_games_over_the_phases(mixed_run, tmp_path, capsys):
    """What ``league.exploit --player nash-team@K --games test`` records (a best-response player, its result in the
    meta table, the best league member's test-game rows), read back: each mixture's test-game win rates with their
    interval, the margin over the best member's test-game rate, and the curve over K in the report."""
    import shutil

    from league.analysis.exploitability import MIXTURE_BEST_RESPONSES, exploitability_curves, mixture_baseline
    from league.analysis.statistics import mean_interval
    from league.config import saved_run_config
    from league.core.players import NewPlayer
    from league.reports.data import gather
    from league.reports.html import exploitability_html
    from league.reports.markdown import exploitability_markdown

    run_dir = tmp_path / "run"
    shutil.copytree(mixed_run, run_dir)
    store = LeagueStore(run_dir)
    try:
        players = store.players()
        mixtures = {k: store_mixture(store, f"nash-team@{k}") for k in (0, 4)}
        members = {k: mixture_baseline(m, players, store.newest_evaluation_rows()).member for k, m in mixtures.items()}
        # On the test games each attacker wins its own share of 100 games against every team, none its dev-game rate.
        test_wins = {a.id: 21 + 10 * i for i, a in enumerate(p for p in players if p.side == "attacker")}
        rows = [OutcomeCount(a, t.id, outcome, count) for a, wins in test_wins.items() for t in players if t.side == "team"
                for outcome, count in (("captured", wins), ("terminal_reached", 100 - wins))]
        records = []
        with store.transaction():
            store.record_evaluation(4, rows, "test")
            for version, (k, wins) in enumerate(((0, 70), (4, 45), (4, 55))):
                br = store.add_player(4, NewPlayer("attacker", "best_response", version, 2, env_steps=600, seed=version,
                                                   env_step_budget=600, from_prior=False))
                records.append({"player": br.name, "mixture": f"nash-team@{k}", "seed": version, "budget": 600,
                                "from_prior": False, "wins": wins, "games": 100, "game_set": "test", "mixture_seed": 0,
                                "iteration": k})
            store.set_meta(MIXTURE_BEST_RESPONSES, records)
        data = gather(store, saved_run_config(run_dir))
    finally:
        store.close()

    assert status.main(["--run-dir", str(run_dir), "--json"]) == 0
    shown = {e["exploited"]: e for e in json.loads(capsys.readouterr().out)["exploitability"]}
    assert set(shown) == {"nash-team@0", "nash-team@4"}
    early, late = shown["nash-team@0"], shown["nash-team@4"]
    assert early["game_set"] == late["game_set"] == "test"
    assert [s["win_rate"] for s in early["seeds"]] == [0.7] and early["win_rate"]["student_t_95_over_seeds"] is None
    assert late["win_rate"]["mean"] == pytest.approx(0.5)
    assert late["win_rate"]["student_t_95_over_seeds"] == pytest.approx(list(mean_interval([0.45, 0.55])))
    # the members chosen on the dev games, their rates and the margins over them the test games'
    for shown_k, k in ((early, 0), (late, 4)):
        member = shown_k["best_member"]
        rate = test_wins[members[k].id] / 100
        assert (member["player"], member["win_rate"], member["game_set"]) == (members[k].name, pytest.approx(rate), "test")
        assert member["margin"]["mean"] == pytest.approx(shown_k["win_rate"]["mean"] - rate)

    [(key, curve)] = exploitability_curves(data.exploitability).items()
    assert key == ("team", "test", 600) and [e.exploited.iteration for e in curve] == [0, 4]
    assert "![exploitability over the phases](exploitability.png)" in exploitability_markdown(data, tmp_path)
    assert (tmp_path / "exploitability.png").stat().st_size > 0
    assert any("id='exploitability'" in part or 'id="exploitability"' in part for part in exploitability_html(data))

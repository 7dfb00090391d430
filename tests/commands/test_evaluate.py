"""``league.evaluate --add-scripted``: measuring an old league against a new scripted player."""

import json

import pytest

from league.core.payoff import ATTACKER_WINS
from league.evaluate import main
from league.state.run_dir import open_run


def members(run_dir):
    _, store = open_run(run_dir)
    try:
        return [p.name for p in store.players()]
    finally:
        store.close()


def test_a_scripted_player_joins_an_old_league_and_is_evaluated(run_copy, capsys):
    before = members(run_copy)
    assert "scripted-evade_defender" not in before

    # A bad name is refused before anything is written, naming it.
    assert main(["--run-dir", str(run_copy), "--workers", "0", "--add-scripted", "evade_defender", "straight+teleport"]) == 2
    assert "straight+teleport" in capsys.readouterr().err
    assert members(run_copy) == before

    args = ["--run-dir", str(run_copy), "--workers", "0", "--episodes", "8", "--players", "team-v1",
            "--add-scripted", "evade_defender", "straight+bisector_intercept"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "| scripted-evade_defender | team-v1 | 8 |" in out
    # The meta-game of the players it evaluated: each group's Nash range beside the LP's vertex.
    assert "| side | group | players | weight at the vertex | range over optimal mixtures |" in out
    assert "Nash mixture (one optimal vertex" in out
    assert main(args) == 0  # a member already: not added twice
    assert members(run_copy) == before + ["scripted-evade_defender", "scripted-straight+bisector_intercept"]

    _, store = open_run(run_copy)
    try:
        evade = next(p for p in store.players() if p.name == "scripted-evade_defender")
        games = sum(r.count for r in store.newest_evaluation_rows() if r.attacker == evade.id)
    finally:
        store.close()
    assert games == 16  # against the chosen team and the added one; the second evaluation replaced the first


def test_the_test_games_are_held_out_from_the_dev_games(run_copy, capsys):
    from envs.scenarios import evaluation_scenarios

    dev, test = evaluation_scenarios("default", 1000), evaluation_scenarios("default", 1000, "test")
    assert not {row.tobytes() for row in dev} & {row.tobytes() for row in test}

    _, store = open_run(run_copy)
    try:
        dev_rows = store.newest_evaluation_rows()
    finally:
        store.close()
    args = ["--run-dir", str(run_copy), "--workers", "0", "--episodes", "8", "--players",
            "attacker-m2-v1", "team-v1", "scripted-lead_intercept"]
    assert main([*args, "--games", "test", "--json"]) == 0
    played = {(p["attacker"], p["team"]): p for p in json.loads(capsys.readouterr().out)["pairs"]}
    _, store = open_run(run_copy)
    try:
        ids = {p.name: p.id for p in store.players()}
        test_rows, after = store.newest_evaluation_rows("test"), store.newest_evaluation_rows()
    finally:
        store.close()
    assert set(after) == set(dev_rows)  # the dev games' results, which the league reads, are untouched
    for (attacker, team), pair in played.items():
        wins = sum(r.count for r in test_rows if (r.attacker, r.team) == (ids[attacker], ids[team]) and r.outcome in ATTACKER_WINS)
        assert (wins, sum(r.count for r in test_rows if (r.attacker, r.team) == (ids[attacker], ids[team]))) == (pair["attacker_wins"], 8)
    assert main([*args, "--games", "dev", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["games"] == "dev"


def test_json_has_the_table_per_reward_method(run_copy, capsys):
    args = ["--run-dir", str(run_copy), "--workers", "0", "--episodes", "4"]
    assert main(args) == 0
    lines = capsys.readouterr().out.splitlines()
    at = next(k for k, line in enumerate(lines) if line.startswith("| reward method | attacker |"))
    header = [cell.strip() for cell in lines[at].strip("|").split("|")]
    end = lines.index("", at)
    rows = [[cell.strip() for cell in line.strip("|").split("|")] for line in lines[at + 2:end]]
    assert main([*args, "--json"]) == 0
    methods = json.loads(capsys.readouterr().out)["methods"]
    # The same numbers as the printed table (method_table), cell for cell.
    assert [[str(m["reward_method"]), m["attacker"]] for m in methods] == [row[:2] for row in rows]
    for method, row in zip(methods, rows):
        assert [c["against"] for c in method["columns"]] == header[2:]
        for cell, printed in zip(method["columns"], row[2:]):
            low, high = cell["interval_95"]
            assert f"{cell['attacker_win_rate']:.3f} [{low:.3f}, {high:.3f}]" == printed
            assert cell["attacker_win_rate"] == cell["attacker_wins"] / cell["games"]
    pool = methods[0]["columns"][-1]
    assert pool["against"] == "league pool" and pool["games"] == 4 * len(pool["teams"]) and pool["starts"] == 4


def test_progress_goes_to_stderr_pair_by_pair_and_json_stays_clean(run_copy, capsys):
    assert main(["--run-dir", str(run_copy), "--workers", "0", "--episodes", "2", "--json"]) == 0
    captured = capsys.readouterr()
    pairs = len(json.loads(captured.out)["pairs"])  # stdout is the JSON object alone
    lines = captured.err.splitlines()
    assert lines[0].startswith("evaluating on 2 dev games each: 1 of ") and "s left" in lines[0]
    assert lines[-1].startswith(f"evaluating on 2 dev games each: {pairs} of {pairs} pairs, ")


def test_progress_lines_are_spaced_in_time():
    from io import StringIO

    from league.cli import PairProgress

    out = StringIO()
    progress = PairProgress("x", every_s=3600, stream=out)
    for done in range(1, 6):
        progress(done, 5)
    assert [line.split(",")[0] for line in out.getvalue().splitlines()] == ["x: 1 of 5 pairs", "x: 5 of 5 pairs"]


def test_json_gives_each_pair_its_win_rate_by_start_class_and_its_free_losses(run_copy, capsys):
    from envs.scenarios import evaluation_scenarios
    from envs.start_classes import classify
    from league.config import saved_run_config

    args = ["--run-dir", str(run_copy), "--workers", "0", "--episodes", "60", "--games", "test",
            "--players", "team-v1", "scripted-lead_intercept", "--json"]
    assert main(args) == 0
    out = json.loads(capsys.readouterr().out)
    game = saved_run_config(run_copy).game
    classes = classify(evaluation_scenarios(game.scenario, 60, "test"), game)
    assert out["start_classes"] == {c: int((classes == c).sum()) for c in ("t_race", "a_certain", "contested")}
    assert all(n > 0 for n in out["start_classes"].values())
    for pair in out["pairs"]:
        by_class = pair["by_start_class"]
        rates = by_class["attacker_win_rate"]
        counts = out["start_classes"]
        # The classes' wins add up to the pair's wins; the free losses are read off the two decided classes.
        assert sum(rates[c] * counts[c] for c in counts) == pytest.approx(pair["attacker_wins"])
        assert by_class["free_losses"] == {"team": rates["t_race"], "attacker": pytest.approx(1 - rates["a_certain"])}

"""Evaluation on the rollout, its workers, the evaluate and report command lines."""

import numpy as np
import pytest
import torch

from envs.agents import Outcome
from envs.config import GameConfig
from envs.match import play, scripted_players
from envs.scenarios import evaluation_scenarios
from envs.scripted import PLAYERS, ScriptedPlayer
from league.config import load_config, saved_run_config
from league.evaluate import main as evaluate_main
from league.evaluation.engine import (
    EvaluationPool, LearnedAgent, deterministic, evaluate_pair, evaluate_pairs, merge, play_fixed_games,
)
from league.rllib.bridge import learner_spec
from league.rollout.games import ScriptedOnState
from league.core.payoff import attacker_won
from league.core.players import Player
from league.report import main as report_main
from league.state.store import LeagueStore

ATTACKER = Player(id=1, side="attacker", kind="scripted", version=0, scripted_attacker="proportional_navigation")
TEAM = Player(id=2, side="team", kind="scripted", version=0, scripted_targeter="straight", scripted_defender="bisector_intercept")


@pytest.mark.parametrize("games", ["dev", "test"])
def test_workers_give_the_numbers_of_a_plain_loop(ray_instance, tmp_path, games):
    game = GameConfig()
    [by_workers] = evaluate_pairs(game, tmp_path, [(ATTACKER, TEAM)], 301, workers=3, games=games)
    [here] = evaluate_pairs(game, tmp_path, [(ATTACKER, TEAM)], 301, games=games)
    plain = play(game, scripted_players("proportional_navigation", "straight", "bisector_intercept"),
                 evaluation_scenarios("default", 301, games))
    for field in ("outcome", "steps", "returns", "attacker_returns"):
        np.testing.assert_array_equal(getattr(by_workers.result, field), getattr(plain, field))
        np.testing.assert_array_equal(getattr(here.result, field), getattr(plain, field))
    assert by_workers.games == 301
    other = play(game, scripted_players("proportional_navigation", "straight", "bisector_intercept"),
                 evaluation_scenarios("default", 301, {"dev": "test", "test": "dev"}[games]))
    assert not np.array_equal(plain.steps, other.steps)  # the other set's games end otherwise


def test_a_lost_worker_is_replayed_here_and_replaced_when_there_is_room(ray_instance, tmp_path):
    """A worker dies (its node did): its games are played in the driver, said in one line, and a
    new worker joins the pool at the next evaluation once Ray has placed it (here at once)."""
    import ray

    game, said = GameConfig(), []
    [expected] = evaluate_pairs(game, tmp_path, [(ATTACKER, TEAM)], 60)
    pool = EvaluationPool(game, tmp_path, workers=2, log=said.append)
    try:
        ray.kill(pool.actors[0])
        [lost] = pool.evaluate([(ATTACKER, TEAM)], 60)
        assert said == ["evaluation worker lost (ActorDiedError): its games are replayed in the driver; "
                        "1 of 2 left, a new one joins when the cluster has room"]
        ray.get(pool.replacements[0][1], timeout=120)  # placed: this instance has room
        [back] = pool.evaluate([(ATTACKER, TEAM)], 60)
        assert said[1:] == ["evaluation worker back: 2 of 2"] and len(pool.actors) == 2
    finally:
        pool.close()
    for result in (lost, back):
        np.testing.assert_array_equal(result.result.outcome, expected.result.outcome)


def assert_same_games(rollout, plain):
    """Bit for bit: both loops step the same core with the same actions, in the same order."""
    for field in ("outcome", "steps", "returns", "attacker_returns"):
        np.testing.assert_array_equal(getattr(rollout, field), getattr(plain, field), err_msg=field)


@pytest.mark.parametrize("attacker", sorted(PLAYERS["attacker"]))
def test_the_rollout_plays_the_fixed_games_as_the_plain_loop(attacker):
    game, positions = GameConfig(), evaluation_scenarios("default", 300)
    plain = play(game, scripted_players(attacker, "avoid_attacker", "bisector_intercept"), positions)
    rollout = play_fixed_games(game, positions, {
        "attacker": ("a", ScriptedOnState(attacker)),
        "targeter": ("t", ScriptedOnState("avoid_attacker")),
        "defender": ("d", ScriptedOnState("bisector_intercept")),
    })
    assert_same_games(rollout, plain)
    assert len(set(plain.outcome.tolist())) > 1  # games that end in different ways


def test_a_learned_team_plays_as_two_controllers_of_the_plain_loop():
    # The rollout runs the team's module once per step over both agents' observations.
    torch.manual_seed(0)
    module = learner_spec(load_config("smoke"), "team").build().eval()
    game, positions = GameConfig(), evaluation_scenarios("default", 300)
    plain = play(game, {
        "attacker": ScriptedPlayer("attacker", "lead_intercept"),
        "targeter": LearnedAgent(module, "targeter"),
        "defender": LearnedAgent(module, "defender"),
    }, positions)
    act = deterministic(module)

    def act_per_agent(obs):
        # The rollout hands the module T's rows, then D's, in one call; the plain loop one agent
        # at a time. A matmul over 600 rows may take another kernel than over 300 and round
        # otherwise, so the forward pass runs per agent: the same shapes in the same order.
        parts = [act(half) for half in np.split(obs, 2)]
        return np.concatenate([p[0] for p in parts]), {}

    rollout = play_fixed_games(game, positions, {
        "attacker": ("scripted", ScriptedOnState("lead_intercept")),
        "targeter": ("team", act_per_agent), "defender": ("team", act_per_agent),
    })
    assert_same_games(rollout, plain)


def test_evaluation_is_deterministic_for_a_fixed_set(tmp_path):
    # A learned team saved once: every evaluation below loads its own module object from it.
    torch.manual_seed(0)
    learner_spec(load_config("smoke"), "team").build().save_to_path(str(tmp_path / "team-v1"))
    learned = Player(id=3, side="team", kind="learner", version=1, checkpoint="team-v1")
    game = GameConfig()
    counts = {}
    for team in (TEAM, learned):
        [whole] = evaluate_pairs(game, tmp_path, [(ATTACKER, team)], 100)
        # The same games played in two slices, as the evaluation workers play them.
        halves = merge([evaluate_pair(game, ATTACKER, team, 50, tmp_path, start).result for start in (0, 50)])
        assert_same_games(halves, whole.result)
        assert int(halves.attacker_wins.sum()) == whole.attacker_wins
        if team.kind == "learner":  # another module object loaded from the same weights
            again = evaluate_pair(game, ATTACKER, team, 100, tmp_path)
            assert_same_games(again.result, whole.result)
        # Other games (the next 100 of the set) are played otherwise: the games played are those asked for.
        later = evaluate_pair(game, ATTACKER, team, 100, tmp_path, start=100)
        assert not np.array_equal(later.result.steps, whole.result.steps), team.name
        counts[team.name] = whole.result.outcome_counts(), later.result.outcome_counts()
    # The scripted pair's games end in different ways, in other numbers on the other games (the
    # untrained team loses every game: the same counts on any set).
    first, later = counts[TEAM.name]
    assert sum(n > 0 for n in first.values()) > 1 and later != first, counts


def markdown_table(out: str, header: str) -> tuple[list[str], list[list[str]]]:
    """The header cells and each row's cells of the Markdown table of ``out`` whose header starts with ``header``."""
    lines = out.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(header))
    table = [[cell.strip() for cell in line.strip().strip("|").split("|")] for line in lines[start:]]
    end = next((i for i, line in enumerate(lines[start:]) if not line.startswith("|")), len(table))
    return table[0], table[2:end]  # the header, past its rule the rows


def test_evaluate_cli_prints_pairs_and_the_method_table(run_copy, capsys):
    assert evaluate_main(["--run-dir", str(run_copy), "--episodes", "30", "--workers", "0"]) == 0
    out = capsys.readouterr().out
    store = LeagueStore(run_copy)
    try:
        names = {p.id: p.name for p in store.players()}
        recorded = {}  # (attacker, team) -> {outcome: games}: each pair's newest evaluation
        for row in store.newest_evaluation_rows():
            recorded.setdefault((names[row.attacker], names[row.team]), {})[row.outcome] = row.count
    finally:
        store.close()
    # The pair table: the games the command recorded in the store, their outcomes and wins / games.
    header, pairs = markdown_table(out, "| attacker | team |")
    labels = header[5:]
    assert labels == [o.label for o in Outcome if o != Outcome.RUNNING]
    assert len(pairs) == 9  # three frozen attackers x three frozen teams
    wins = {}
    for attacker, team, games, rate, _interval, *counts in pairs:
        outcomes = recorded[(attacker, team)]
        assert dict(zip(labels, map(int, counts))) == {label: outcomes.get(label, 0) for label in labels}
        assert sum(outcomes.values()) == int(games) == 30
        wins[(attacker, team)] = sum(n for label, n in outcomes.items() if attacker_won(label))
        assert rate == f"{wins[(attacker, team)] / 30:.3f}", (attacker, team)
    assert len({row[3] for row in pairs}) > 1  # not one rate for every pair
    # The method table: method 2's newest snapshot, its rate against each team and pooled over the
    # league's teams, by hand from the recorded wins (the rates; not the intervals).
    header, [row] = markdown_table(out, "| reward method | attacker |")
    assert row[:2] == ["2", "attacker-m2-v1"]
    assert header[2:] == ["scripted-avoid_attacker+pure_pursuit", "team-v1", "league pool"]
    teams = [team for attacker, team in wins if attacker == "attacker-m2-v1"]
    for column, cell in zip(header[2:], row[2:]):
        against = teams if column == "league pool" else [column]
        pooled = sum(wins[("attacker-m2-v1", team)] for team in against) / (30 * len(against))
        assert cell.split()[0] == f"{pooled:.3f}", (column, cell)
    assert evaluate_main(["--run-dir", str(run_copy), "--players", "nobody"]) == 2


def test_training_wrote_evaluations_every_k_iterations(tiny_run):
    every = saved_run_config(tiny_run).evaluation.every_iterations
    store = LeagueStore(tiny_run)
    try:
        last = store.iteration_count()
        phase_learner = {row["iteration"]: row["learner_side"] for row in store.iteration_rows()}
        learners = {p.id: p.side for p in store.players(kind="learner")}
        pairs = store.db.execute(
            "SELECT DISTINCT iteration, attacker, team FROM matches WHERE source = 'evaluation'"
        ).fetchall()
    finally:
        store.close()
    assert every == 2 and last == 4  # the tiny run: two evaluations during training
    # The learners' evaluations during training: at every k-th iteration and no other, each of
    # the learner of that iteration's phase.
    during = {}
    for iteration, attacker, team in pairs:
        for player in {attacker, team} & learners.keys():
            during.setdefault(iteration, set()).add(learners[player])
    assert sorted(during) == [i for i in range(1, last + 1) if i % every == 0]
    assert all(sides == {phase_learner[i]} for i, sides in during.items()), during
    # The frozen league's evaluation: once, at the final iteration.
    frozen = {iteration for iteration, attacker, team in pairs if not {attacker, team} & learners.keys()}
    assert frozen == {last}


def test_report_holds_the_expected_files(run_copy):
    assert report_main(["--run-dir", str(run_copy)]) == 0
    report = run_copy / "report"
    text = (report / "report.md").read_text()
    assert "Table 1 analogue" in text and "| 2 | attacker-m2-v1 |" in text and "0.6253" in text
    for name in ("payoff.png", "ratings.png", "win_rates.png", "returns.png", "curves.png"):
        assert (report / name).read_bytes()[:4] == b"\x89PNG"
        assert f"]({name})" in text
    assert list(report.glob("trajectory_attacker_*.png")) and list(report.glob("trajectory_team_*.png"))
    page = (report / "index.html").read_text()
    assert "Table 1 analogue" in page and "attacker-m2-v1" in page
    assert "<script src" not in page and "<link" not in page  # self-contained: opens offline

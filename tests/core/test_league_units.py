"""League pieces that need no running Ray: config, PFSP, match plans, payoff, modules, store."""

import numpy as np
import pytest
import torch

from league.config import CONFIG_DIR, ConfigError, RunConfig, load_config
from league.analysis.statistics import wilson_interval
from envs.agents import Outcome
from league.core.payoff import ATTACKER_WINS, OutcomeCount, aggregate, attacker_won, elo_ratings, player_record, record_against, win_rate, wins_of
from league.core.players import NewPlayer, Player
from league.core.pfsp import pfsp_probabilities, with_scripted_share
from league.core.match_plan import MatchPlan
from league.rllib.bridge import learner_spec
from league.run import main as run_main
from league.state.store import LeagueStore
from ray.rllib.core.columns import Columns


# ---------------------------------------------------------------- config
def write(tmp_path, text):
    path = tmp_path / "run.yaml"
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize(
    "text, key",
    [
        ("name: x\nppo: {learning_rate: 0.1}\n", "ppo.learning_rate"),
        ("name: x\nppo: {train_batch_size: lots}\n", "ppo.train_batch_size"),
        ("name: x\ngame: {v_attacker: 0.1}\n", "v_attacker"),
        ("name: x\nppo: {train_batch_size: 100, minibatch_size: 200}\n", "minibatch_size"),
        ("name: x\nleague: {scripted_attackers: [teleport]}\n", "teleport"),
        ("name: x\nleague: {mode: protocol}\n", "phases"),
        ("seed: 1\n", "name"),
        ("name: x\nresources: {sampler: turbo}\n", "resources.sampler"),
        ("name: x\nevaluation: {custom_resources_per_worker: {evaluator: many}}\n", "custom_resources_per_worker"),
        ("name: x\nppo: {team_gamma: 1.5}\n", "ppo.team_gamma"),
        # RLlib's own GAE (batched and standard samplers) has one discount for every module.
        ("name: x\nppo: {team_gamma: 0.999}\nresources: {sampler: batched}\n", "team_gamma"),
        ("name: x\nppo: {minibatch_counts: env_steps}\nresources: {sampler: standard}\n", "minibatch_counts"),
        ("name: x\nppo: {minibatch_counts: games}\n", "ppo.minibatch_counts"),
        ("name: x\nppo: {targeter_shaping: -1}\n", "ppo.targeter_shaping"),
        ("name: x\nppo: {targeter_shaping: 3}\nresources: {sampler: batched}\n", "targeter_shaping"),
        ("name: x\nppo: {defender_shaping: 3}\nresources: {sampler: batched}\n", "defender_shaping"),
        ("name: x\nppo: {attacker_win_reward: 70}\nresources: {sampler: standard}\n", "attacker_win_reward"),
        ("name: x\nppo: {team_reward: shared}\nresources: {sampler: standard}\n", "team_reward"),
        ("name: x\nppo: {bf16: true}\nresources: {sampler: batched}\n", "bf16"),  # RLlib's own loss has no autocast
        ("name: x\nppo: {team_reward: mine}\n", "ppo.team_reward"),
        ("name: x\nleague: {frozen_players_explore: false}\nresources: {sampler: standard}\n", "frozen_players_explore"),
        ("name: x\nppo: {lr_schedule: [[100, 0.001]]}\n", "lr_schedule"),
        ("name: x\nppo: {attacker_prior: lead_intercept}\ngame: {observation: paper}\n", "attacker_prior"),
        ("name: x\nppo: {attacker_prior: pure_pursuit}\n", "ppo.attacker_prior"),
        ("name: x\nppo: {team_prior: straight+pure_pursuit}\ngame: {action_mode: absolute}\n", "team_prior"),
        ("name: x\nppo: {attacker_heading_cosines: true}\ngame: {observation: paper}\n", "attacker_heading_cosines"),
        ("name: x\nppo: {lr_schedule: [[0, 0.001], [0, 0.0001]]}\n", "lr_schedule"),
    ],
)
def test_invalid_config_names_the_key(tmp_path, text, key):
    with pytest.raises(ConfigError, match=key):
        load_config(write(tmp_path, text))


def test_every_shipped_config_is_valid():
    names = {path.stem for path in CONFIG_DIR.glob("*.yaml")}
    assert {"smoke", "selfplay_league", "cluster"} | {f"attacker_method{n}{paper}" for n in (1, 2, 3) for paper in ("", "_paper")} <= names
    for name in names:
        assert load_config(name).name == name


def test_the_cluster_config_is_the_smoke_league_placed_on_nodes():
    from league.config import changed_keys

    smoke, cluster = (load_config(name).model_dump(mode="json") for name in ("smoke", "cluster"))
    placement = ("name", "resources.", "evaluation.workers", "evaluation.cpus_per_worker", "evaluation.custom_resources")
    assert [key for key in changed_keys(smoke, cluster) if not key.startswith(placement)] == []
    assert cluster["resources"]["custom_resources_per_env_runner"] == {"sampler": 1}
    assert cluster["evaluation"]["custom_resources_per_worker"] == {"evaluator": 1}


def test_set_overrides_and_bad_yaml(tmp_path):
    config = load_config("smoke", ["ppo.lr=0.001", "game.attacker_reward=3"])
    assert config.ppo.lr == 0.001 and config.game.attacker_reward == 3
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(write(tmp_path, "name: [x\n"))
    with pytest.raises(ConfigError, match="not found"):
        load_config("no_such_config")
    with pytest.raises(ConfigError, match="key=value"):
        load_config("smoke", ["ppo.lr"])


def test_a_bad_key_given_with_set_is_reported_as_coming_from_set(tmp_path):
    with pytest.raises(ConfigError) as err:
        load_config("smoke", ["ppo.lrr=1"])
    assert str(err.value).startswith("--set ppo.lrr=1: ppo.lrr: ") and "smoke.yaml" not in str(err.value)
    bad_file = write(tmp_path, "name: x\nppo: {lrr: 1}\n")
    with pytest.raises(ConfigError, match=r"run\.yaml: ppo\.lrr: "):  # a key from the file still names the file
        load_config(bad_file, ["seed=3"])


def test_run_exits_2_on_bad_config_and_writes_nothing(tmp_path, capsys):
    run_dir = tmp_path / "run"
    assert run_main(["--config", write(tmp_path, "name: x\nppo: {bogus: 1}\n"), "--run-dir", str(run_dir)]) == 2
    assert "ppo.bogus" in capsys.readouterr().err
    assert not run_dir.exists()
    assert run_main(["--config", "smoke", "--run-dir", str(run_dir), "--set", "league.pfsp=best"]) == 2
    assert "league.pfsp" in capsys.readouterr().err and not run_dir.exists()


def test_resume_of_a_non_run_exits_2(tmp_path, capsys):
    assert run_main(["--resume", str(tmp_path)]) == 2
    assert "not a league run directory" in capsys.readouterr().err


# ---------------------------------------------------------------- PFSP and match plans
def test_a_scripted_share_holds_that_much_of_the_mass_for_the_scripted_players_weighted_by_pfsp():
    x = [0.9, 0.5, 0.1]  # the first two scripted
    p = pfsp_probabilities(x, "squared")
    shared = with_scripted_share(x, [True, True, False], 0.5, "squared")
    np.testing.assert_allclose(shared, 0.5 * p + 0.5 * np.array([0.01, 0.25, 0.0]) / 0.26)
    assert abs(shared.sum() - 1) < 1e-12  # float64 sums of three terms
    np.testing.assert_array_equal(with_scripted_share(x, [False] * 3, 0.5, "squared"), p)  # none scripted: PFSP alone
    np.testing.assert_array_equal(with_scripted_share(x, [True, True, False], 0.0, "squared"), p)


def test_a_uniform_scripted_share_still_meets_a_scripted_player_the_learner_always_beats():
    x = [1.0, 0.5, 0.1]  # the first two scripted; squared gives the first no games
    assert with_scripted_share(x, [True, True, False], 0.5, "squared")[0] == 0.0
    shared = with_scripted_share(x, [True, True, False], 0.5, "squared", scripted_weighting="uniform")
    np.testing.assert_allclose(shared, 0.5 * pfsp_probabilities(x, "squared") + 0.5 * np.array([0.5, 0.5, 0.0]))


def test_the_nash_weighting_is_the_given_mixture_whatever_the_win_rates():
    x = [0.9, 0.5, 0.1]
    np.testing.assert_allclose(pfsp_probabilities(x, "nash", [0.2, 0.0, 0.6]), [0.25, 0.0, 0.75])
    np.testing.assert_allclose(pfsp_probabilities(x, "nash", [0.0, 0.0, 0.0]), [1 / 3] * 3)  # all zero: uniform
    # the scripted share spreads over the scripted candidates by their Nash weights
    shared = with_scripted_share(x, [True, True, False], 0.5, "nash", [0.2, 0.0, 0.6])
    np.testing.assert_allclose(shared, 0.5 * np.array([0.25, 0.0, 0.75]) + 0.5 * np.array([1.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="Nash weight"):
        pfsp_probabilities(x, "nash")


def test_pfsp_weightings():
    np.testing.assert_allclose(pfsp_probabilities([0.0, 0.5, 1.0], "squared"), [0.8, 0.2, 0.0])
    np.testing.assert_allclose(pfsp_probabilities([0.5, 0.9], "variance"), [0.25 / 0.34, 0.09 / 0.34])
    np.testing.assert_allclose(pfsp_probabilities([0.2, 0.9], "uniform"), [0.5, 0.5])
    np.testing.assert_allclose(pfsp_probabilities([1.0, 1.0], "squared"), [0.5, 0.5])  # all zero: uniform
    with pytest.raises(ValueError):
        pfsp_probabilities([], "squared")


class FakeEpisode:
    def __init__(self, id_):
        self.id_ = id_


def test_match_plan_decides_once_per_episode_and_follows_the_probabilities():
    opponents = [{"attacker": "a0"}, {"attacker": "a1"}, {"attacker": "a2"}]
    plan = MatchPlan([{"targeter": "team", "defender": "team"}], [opponents], [[0.6, 0.3, 0.1]], seed=5)
    counts = np.zeros(3)
    for i in range(6000):
        episode = FakeEpisode(f"{i:032x}")
        chosen = plan("attacker", episode)
        assert plan("attacker", episode) == chosen  # asked again: same answer
        assert plan("targeter", episode) == plan("defender", episode) == "team"  # one shared team module
        counts[int(chosen[1])] += 1
    expected = np.array([0.6, 0.3, 0.1]) * 6000
    assert np.all(np.abs(counts - expected) < 4 * np.sqrt(expected))


def test_match_plan_with_several_learners_gives_each_its_own_opponents():
    team_a, team_b = {"targeter": "ta", "defender": "da"}, {"targeter": "tb", "defender": "db"}
    plan = MatchPlan(
        [{"attacker": "attacker-m1"}, {"attacker": "attacker-m3"}], [[team_a, team_b], [team_a, team_b]],
        [[1.0, 0.0], [0.0, 1.0]], seed=2,
    )
    seen = set()
    for i in range(400):
        episode = FakeEpisode(f"e{i}")
        match = (plan("attacker", episode), plan("targeter", episode), plan("defender", episode))
        assert match in {("attacker-m1", "ta", "da"), ("attacker-m3", "tb", "db")}
        seen.add(match[0])
    assert seen == {"attacker-m1", "attacker-m3"}


# ---------------------------------------------------------------- payoff and intervals
def test_unplayed_pair_is_even_and_elo_orders_players():
    assert win_rate(0, 0) == 0.5
    ratings = elo_ratings([(1, 2, 80, 100), (3, 2, 20, 100)], [1, 2, 3])
    assert ratings[1] > ratings[2] > ratings[3]
    even = elo_ratings([(1, 2, 50, 100)], [1, 2])
    assert even[1] == pytest.approx(even[2])


def test_who_wins_each_outcome_and_from_which_side():
    assert ATTACKER_WINS == {"captured", "timeout"}
    assert [attacker_won(o.label) for o in Outcome if o != Outcome.RUNNING] == [True, True, False, False]
    # attacker 1 vs team 2: 3 captures, 1 timeout, 6 times T reached the terminal
    rows = [OutcomeCount(*row) for row in
            [(1, 2, "captured", 3), (1, 2, "timeout", 1), (1, 2, "terminal_reached", 6), (4, 2, "attacker_intercepted", 5)]]
    assert [row.wins("team") for row in rows] == [0, 0, 6, 5]
    table = aggregate(rows)
    assert table == {(1, 2): (4, 10), (4, 2): (0, 5)}
    assert record_against(table, "attacker", 1, 2) == (4, 10)
    assert record_against(table, "team", 2, 1) == (6, 10)
    assert record_against(table, "team", 2, 3) == (0, 0)  # never played
    assert player_record(table, "team", 2) == (11, 15)
    assert player_record(table, "attacker", 4) == (0, 5)
    assert wins_of("team", np.array([1, 0, 1]), 1).tolist() == [0, 1, 0]  # single games


def test_the_paper_team_is_recognised_by_its_scripted_players():
    paper = Player("team", "scripted", 0, scripted_targeter="avoid_attacker", scripted_defender="pure_pursuit", id=1)
    other = Player("team", "scripted", 0, scripted_targeter="straight", scripted_defender="pure_pursuit", id=2)
    assert paper.is_paper_team and not other.is_paper_team
    assert not Player("team", "snapshot", 1, id=3).is_paper_team


@pytest.mark.parametrize(
    "wins, games, low, high", [(0, 10, 0.0, 0.2775), (5, 10, 0.2366, 0.7634), (8, 10, 0.4902, 0.9433)]
)
def test_wilson_interval_known_values(wins, games, low, high):
    assert wilson_interval(wins, games) == pytest.approx((low, high), abs=1e-4)


# ---------------------------------------------------------------- the team's centralized critic
@pytest.fixture(scope="module")
def modules():
    run = RunConfig(name="t", ppo={"hidden": [16, 16]})
    return {side: learner_spec(run, side).build() for side in ("attacker", "team")}


def test_team_critic_reads_the_global_state_and_the_role_and_the_actor_does_not(modules):
    team = modules["team"]
    own = team.actor_inputs
    obs = torch.randn(8, team.observation_space.shape[0])
    assert obs.shape[1] - own == 22  # the appended global state
    obs[:, own - 2 : own] = torch.tensor([1.0, 0.0])  # all targeters
    other_own = obs.clone()
    other_own[:, : own - 2] = torch.randn(8, own - 2)  # same role, different own view
    other_state = obs.clone()
    other_state[:, own:] = torch.randn(8, 22)
    other_role = obs.clone()
    other_role[:, own - 2 : own] = torch.tensor([0.0, 1.0])  # the defenders at the same global state
    values = team.compute_values({Columns.OBS: obs})
    torch.testing.assert_close(team.compute_values({Columns.OBS: other_own}), values)
    assert not torch.allclose(team.compute_values({Columns.OBS: other_state}), values)
    assert not torch.allclose(team.compute_values({Columns.OBS: other_role}), values)
    actions = team.deterministic_action(obs)
    torch.testing.assert_close(team.deterministic_action(other_state), actions)
    assert not torch.allclose(team.deterministic_action(other_own), actions)


def test_team_critic_learns_different_values_for_t_and_d_at_one_state():
    """T and D are paid differently (Eq. 10, 11): at the same global state the critic must
    be able to fit both returns, which a critic blind to the role cannot (it fits their mean)."""
    torch.manual_seed(0)
    team = learner_spec(RunConfig(name="t", ppo={"hidden": [16, 16]}), "team").build()
    own = team.actor_inputs
    state = torch.randn(64, team.observation_space.shape[0])
    targeters, defenders = state.clone(), state.clone()
    targeters[:, own - 2 : own] = torch.tensor([1.0, 0.0])
    defenders[:, own - 2 : own] = torch.tensor([0.0, 1.0])
    obs = torch.cat((targeters, defenders))
    returns = torch.cat((torch.full((64,), -1.0), torch.full((64,), 1.0)))
    optimizer = torch.optim.Adam(team.vf.parameters(), lr=1e-2)
    for _ in range(300):
        loss = (team.compute_values({Columns.OBS: obs}) - returns).pow(2).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    # Blind to the role, the best fit is 0 for every row: a squared error of 1.
    assert loss.item() < 0.01


def test_attacker_critic_is_local(modules):
    attacker = modules["attacker"]
    obs = torch.randn(8, attacker.observation_space.shape[0])
    other_state = obs.clone()
    other_state[:, attacker.actor_inputs :] = torch.randn(8, 22)
    torch.testing.assert_close(attacker.compute_values({Columns.OBS: other_state}), attacker.compute_values({Columns.OBS: obs}))


# ---------------------------------------------------------------- store
def test_rollback_forgets_later_iterations(tmp_path):
    store = LeagueStore(tmp_path, create=True)
    with store.transaction():
        a = store.add_player(0, NewPlayer(side="attacker", kind="scripted", version=0, scripted_attacker="lead_intercept"))
        t = store.add_player(0, NewPlayer(side="team", kind="learner", version=0))
    for iteration in (1, 2, 3):
        with store.transaction():
            store.record_outcomes(iteration, "training", [OutcomeCount(a.id, t.id, "captured", 2)])
            store.record_iteration(iteration, phase=0, learner_side="team", env_steps=iteration, episodes=2 * iteration,
                                   steps_per_second=1.0, wall_seconds=1.0)
            if iteration == 2:
                store.add_player(iteration, NewPlayer(side="team", kind="snapshot", version=1, parent=t.id))
    store.rollback_after(1)
    assert store.iteration_count() == 1
    assert store.outcome_rows() == [OutcomeCount(a.id, t.id, "captured", 2)]
    assert [p.kind for p in store.players()] == ["scripted", "learner"]


def test_reproduce_reads_the_paper_teams_test_games_not_the_dev_games(tmp_path):
    import yaml

    from league.config import RUN_CONFIG_FILE, RunConfig
    from envs.agents import Outcome
    from league.studies.table_one import attacker_win_rate

    (tmp_path / RUN_CONFIG_FILE).write_text(yaml.safe_dump(RunConfig(name="x").model_dump(mode="json")))
    store = LeagueStore(tmp_path, create=True)
    with store.transaction():
        straight = store.add_player(0, NewPlayer(side="team", kind="scripted", version=0, scripted_targeter="straight",
                                    scripted_defender="pure_pursuit"))
        paper = store.add_player(0, NewPlayer(side="team", kind="scripted", version=0, scripted_targeter="avoid_attacker",
                                 scripted_defender="pure_pursuit"))
        v1 = store.add_player(0, NewPlayer(side="attacker", kind="snapshot", version=1, reward_method=2))
    stats = dict(games=4, attacker_return_1=0.0, attacker_return_2=0.0, attacker_return_3=0.0, targeter_return=0.0,
                 defender_return=0.0, mean_steps=9.0)
    store.record_evaluation(2, [OutcomeCount(v1.id, paper.id, "captured", 1), OutcomeCount(v1.id, paper.id, "terminal_reached", 3)])
    three_of_four = bytes([Outcome.CAPTURED, Outcome.CAPTURED, Outcome.CAPTURED, Outcome.TERMINAL_REACHED])
    store.record_evaluation_stats(2, "test", v1.id, paper.id, {**stats, "attacker_wins": 3}, three_of_four)
    store.record_evaluation_stats(2, "test", v1.id, straight.id, {**stats, "attacker_wins": 4}, bytes([Outcome.CAPTURED] * 4))
    store.close()
    assert attacker_win_rate(tmp_path, 2, episodes=4) == (0.75, 4)


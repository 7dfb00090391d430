"""The fast path: PPO's training batch from the sampler's arrays equals RLlib's from episodes."""

import contextlib
import copy
import numpy as np
import pytest
import torch

from league.config import RunConfig
from league.core.players import Player
from envs.agents import AGENTS, Outcome
from envs.observations import GLOBAL_STATE_SIZE, interception_distance, terminal_distance
from league.core.match_plan import MatchPlan
from league.rllib import learner as learner_module
from league.rllib.algorithm import COMPILED_LOSS, MINIBATCH_SIZES, RESIDUAL_PENALTIES, RESIDUAL_PENALTY_GATED, LeaguePPO, training_batch
from league.rllib.bridge import build_config, episode_outcomes, learner_settings, learner_spec, set_trainable
from league.rollout.train_batch import gae, minibatch_rows
from league.rollout.training_reward import potential_shaping
from ray.rllib.algorithms.ppo.torch.ppo_torch_learner import PPOTorchLearner
from ray.rllib.connectors.learner import AddOneTsToEpisodesAndTruncate, GeneralAdvantageEstimation
from ray.rllib.core.columns import Columns
from ray.rllib.evaluation.postprocessing import Postprocessing
from ray.rllib.policy.sample_batch import MultiAgentBatch, SampleBatch
from ray.rllib.utils.metrics import ALL_MODULES, NUM_ENV_STEPS_SAMPLED_LIFETIME
from ray.rllib.utils.minibatch_utils import MiniBatchCyclicIterator

GAMES = 6
ATTACKER = Player(id=1, side="attacker", kind="learner", version=0, reward_method=3)
TEAM = Player(id=2, side="team", kind="learner", version=0)
SCRIPTED_TEAM = Player(
    id=3, side="team", kind="scripted", version=0, scripted_targeter="avoid_attacker", scripted_defender="pure_pursuit"
)


def test_gae_cuts_at_game_ends_and_bootstraps_truncated_games():
    gamma, lam = 0.9, 0.8
    rewards = np.array([[1.0, 0.5], [2.0, -1.0], [0.0, 3.0]])
    values = np.array([[0.3, 0.1], [0.2, -0.4], [0.6, 0.7]])
    ended = np.array([[0, 0], [1, 0], [0, 0]], dtype=float)  # game 0 ends on step 1 and starts anew on step 2
    bootstrap = np.array([0.25, -0.5])
    advantages, targets = gae(rewards, values, bootstrap, ended, gamma, lam)
    # By hand, as the lambda-weighted sum of one-step TD errors along each episode.
    d00 = 1.0 + gamma * 0.2 - 0.3
    d10 = 2.0 - 0.2  # the game ended: nothing after it
    d20 = 0.0 + gamma * 0.25 - 0.6  # a truncated chunk: bootstrapped
    d01, d11, d21 = 0.5 + gamma * -0.4 - 0.1, -1.0 + gamma * 0.7 + 0.4, 3.0 + gamma * -0.5 - 0.7
    expected = np.array(
        [
            [d00 + gamma * lam * d10, d01 + gamma * lam * d11 + (gamma * lam) ** 2 * d21],
            [d10, d11 + gamma * lam * d21],
            [d20, d21],
        ]
    )
    np.testing.assert_allclose(advantages, expected, rtol=1e-12)
    np.testing.assert_allclose(targets, expected + values, rtol=1e-12)


def test_potential_shaping_sums_to_the_start_potential_over_every_finished_game():
    # Two games of three steps: game 0 ends on step 1 (a new one starts on step 2), game 1 runs on.
    potentials = np.array([[-3.0, -2.0], [-2.5, -2.2], [-1.0, -1.5], [-0.8, -1.4]])
    ended = np.array([[0, 0], [1, 0], [0, 0]], dtype=float)
    shaping = potential_shaping(potentials, ended, gamma=1.0)
    # Game 0's first episode: whatever the path, its shaping sums to -Phi(s_0) (potential 0 after the end).
    assert shaping[0, 0] + shaping[1, 0] == 3.0
    # A game still running at the last row is shaped toward the state after it.
    np.testing.assert_array_equal(shaping[:, 1], [-2.2 + 2.0, -1.5 + 2.2, -1.4 + 1.5])
    # With a discount, gamma * Phi(s') - Phi(s), step by step.
    np.testing.assert_allclose(potential_shaping(potentials, ended, gamma=0.9)[0], [0.9 * -2.5 + 3.0, 0.9 * -2.2 + 2.0], rtol=1e-15)


# The team discounts differently from the attacker (`PPOSettings.team_gamma`): each module's GAE must use its own.
RUN = RunConfig(
    name="fast",
    seed=3,
    ppo={
        "train_batch_size": 300, "minibatch_size": 100, "num_epochs": 1, "hidden": [16],
        "team_gamma": 0.999, "team_lambda_": 0.8,
    },
    resources={"num_envs_per_env_runner": GAMES, "sampler": "fast"},
)
SIDES = {ATTACKER.name: ATTACKER.side, TEAM.name: TEAM.side}


@pytest.fixture(scope="module")
def algo(ray_instance):
    # Half the games against the learning team, half against the scripted one: mixed matches.
    plan = MatchPlan([{"attacker": ATTACKER.name}], [[TEAM.modules(), SCRIPTED_TEAM.modules()]], [[1.0, 1.0]], seed=0)
    built = build_config(RUN, [ATTACKER, TEAM, SCRIPTED_TEAM], plan).build_algo()
    yield built
    built.stop()


def rows_by_step(columns):
    """Row index by (observation, action) bytes: the same step found in either batch."""
    return {
        (obs.tobytes(), action.tobytes()): i for i, (obs, action) in enumerate(zip(columns[Columns.OBS], columns[Columns.ACTIONS]))
    }


def test_value_targets_and_advantages_are_those_of_rllibs_learner_connector(algo):
    assert isinstance(algo, LeaguePPO)
    runner = algo.env_runner
    # One play of the games gives both: the episodes RLlib's pipeline takes, and the arrays.
    runner._reset_all()
    done, rows, t = runner._play(40, None, True, False)
    episodes = done + runner.chunks.ongoing(rows, t)
    fast = runner._training_data(rows, t)
    assert set(fast) == {ATTACKER.name, TEAM.name}
    assert any(e.is_done for e in episodes) and any(not e.is_done for e in episodes)

    def connector_batch(learner):
        # The pipeline PPO's Learner builds for itself (`PPOLearner.build`), its GAE step run
        # once per module with that module's discount (RLlib's GAE has one for all).
        pipeline = learner.config.build_learner_connector(None, None)
        pipeline.prepend(AddOneTsToEpisodesAndTruncate())
        shared = pipeline(rl_module=learner.module, batch={}, episodes=episodes, shared_data={})
        columns = {}
        for m in fast:
            gamma, lambda_ = RUN.ppo.discount(SIDES[m])
            fresh = {module_id: dict(data) for module_id, data in shared.items()}
            batch = GeneralAdvantageEstimation(gamma=gamma, lambda_=lambda_)(rl_module=learner.module, batch=fresh, episodes=episodes)
            values = learner.module[m].compute_values(batch[m])
            columns[m] = {k: np.asarray(v.detach() if torch.is_tensor(v) else v) for k, v in {**batch[m], "values": values}.items()}
        return columns

    [call] = algo.learner_group.foreach_learner(connector_batch)
    standard = call.get()
    for module_id, columns in fast.items():
        reference = standard[module_id]
        real = reference[Columns.LOSS_MASK].astype(bool)  # RLlib appends one bootstrap step per chunk
        index = rows_by_step(columns)
        order = [index[key] for key in zip(*(map(bytes, reference[c][real]) for c in (Columns.OBS, Columns.ACTIONS)))]
        assert sorted(order) == list(range(len(columns[Columns.OBS])))  # the same steps, each once
        for key in (Columns.ACTION_LOGP, Columns.ACTION_DIST_INPUTS):
            np.testing.assert_array_equal(columns[key][order], reference[key][real])
        # RLlib runs GAE in float32 over chunks of up to 40 steps with values and returns of
        # size ~1 to 10: rounding of ~40 * 6e-8 * 10 = 2.4e-5 at most; ours runs in float64.
        targets = reference[Postprocessing.VALUE_TARGETS][real]
        np.testing.assert_allclose(columns[Postprocessing.VALUE_TARGETS][order], targets, rtol=0, atol=3e-5)
        # Raw advantages (before standardising, which RLlib does over its bootstrap steps too).
        raw = targets - reference["values"][real]
        ours = columns[Postprocessing.ADVANTAGES][order]
        np.testing.assert_allclose(ours, raw, rtol=0, atol=3e-5)


def test_a_fast_training_iteration_trains_the_learners_and_counts_matches(algo):
    set_trainable(algo, [ATTACKER.name])
    def weights():
        return {m: {k: np.array(v) for k, v in w.items()} for m, w in algo.learner_group.get_weights([ATTACKER.name, TEAM.name]).items()}

    before = weights()
    result = algo.train()
    after = weights()
    assert any(not np.array_equal(before[ATTACKER.name][k], after[ATTACKER.name][k]) for k in before[ATTACKER.name])
    assert all(np.array_equal(before[TEAM.name][k], after[TEAM.name][k]) for k in before[TEAM.name])  # not trained now
    runners = result["env_runners"]
    assert runners["num_env_steps_sampled"] >= 300
    # One epoch over the attacker's 300 steps (50 steps of 6 games; it plays each env step once).
    assert result["learners"][ATTACKER.name]["num_module_steps_trained"] == 300
    played = episode_outcomes(result)
    assert sum(count for _, _, count in played) == runners["num_episodes"] > 0
    assert {modules[1:] for modules, _, _ in played} <= {tuple(TEAM.modules().values()), tuple(SCRIPTED_TEAM.modules().values())}


def gradient_steps(algo, module_id: str) -> int:
    """Adam's step count of ``module_id``'s parameters: one per minibatch it was trained on."""
    def steps(learner) -> int:
        return max((int(state["step"]) for state in learner.get_optimizer(module_id).state.values()), default=0)

    return next(r.get() for r in algo.learner_group.foreach_learner(steps) if r.ok)


def test_an_exploiter_learns_in_its_sides_minibatches():
    # A team exploiter trains in the same update as the team learner: a different minibatch
    # size would stop that update (`league.rllib.algorithm.minibatch_size`).
    run = RunConfig(**{**RUN.model_dump(), "ppo": {**RUN.ppo.model_dump(), "minibatch_counts": "env_steps"}})
    exploiter = Player(id=4, side="team", kind="exploiter", version=0)
    plan = MatchPlan([{"attacker": ATTACKER.name}], [[TEAM.modules()]], [[1.0]], seed=0)
    sizes = build_config(run, [ATTACKER, TEAM, exploiter, SCRIPTED_TEAM], plan).learner_config_dict[MINIBATCH_SIZES]
    assert sizes == {ATTACKER.name: 100, TEAM.name: 200, exploiter.name: 200}


def test_the_residual_penalty_reaches_the_attacker_learners_loss_only():
    run = RunConfig(**{**RUN.model_dump(), "ppo": {**RUN.ppo.model_dump(), "attacker_prior": "lead_intercept",
                                                   "attacker_residual_penalty": 0.5,
                                                   "attacker_residual_penalty_gate": "until_targeter_turns"},
                       "game": {**RUN.game.model_dump(), "attacker_memory": True}})
    exploiter = Player(id=4, side="attacker", kind="exploiter", version=0, reward_method=2)
    plan = MatchPlan([{"attacker": ATTACKER.name}], [[TEAM.modules()]], [[1.0]], seed=0)
    config = build_config(run, [ATTACKER, exploiter, TEAM, SCRIPTED_TEAM], plan)
    assert config.learner_config_dict[RESIDUAL_PENALTIES] == {ATTACKER.name: 0.5, exploiter.name: 0.5}
    assert config.learner_config_dict[RESIDUAL_PENALTY_GATED] is True


def test_minibatches_counted_in_env_steps_give_the_team_twice_the_rows(algo):  # `algo`: Ray is up
    # `ppo.minibatch_counts: env_steps`: T and D give the team two rows per env step; in
    # minibatches of twice the rows it takes as many gradient steps per env step as the attacker.
    run = RunConfig(**{**RUN.model_dump(), "ppo": {**RUN.ppo.model_dump(), "minibatch_counts": "env_steps"}})
    plan = MatchPlan([{"attacker": ATTACKER.name}], [[TEAM.modules()]], [[1.0]], seed=0)  # the team in every game
    own = build_config(run, [ATTACKER, TEAM, SCRIPTED_TEAM], plan).build_algo()
    try:
        set_trainable(own, [ATTACKER.name])
        result = own.train()
        assert result["learners"][ATTACKER.name]["num_module_steps_trained"] == 300
        assert gradient_steps(own, ATTACKER.name) == 3  # 300 rows in minibatches of 100, one epoch
        set_trainable(own, [TEAM.name])
        result = own.train()
        assert result["learners"][TEAM.name]["num_module_steps_trained"] == 600
        assert gradient_steps(own, TEAM.name) == 3  # 600 rows in minibatches of 200
        assert gradient_steps(own, ATTACKER.name) == 3  # not trained in the team's iteration
    finally:
        own.stop()


def test_the_team_takes_its_own_epoch_count(algo):  # `algo`: Ray is up
    # `ppo.team_num_epochs`: the team passes its batch that many times, the attacker `num_epochs` times.
    run = RunConfig(**{**RUN.model_dump(), "ppo": {**RUN.ppo.model_dump(), "team_num_epochs": 2}})
    plan = MatchPlan([{"attacker": ATTACKER.name}], [[TEAM.modules()]], [[1.0]], seed=0)  # the team in every game
    own = build_config(run, [ATTACKER, TEAM, SCRIPTED_TEAM], plan).build_algo()
    try:
        set_trainable(own, [ATTACKER.name])
        own.train()
        assert gradient_steps(own, ATTACKER.name) == 3  # 300 rows in minibatches of 100, one epoch
        set_trainable(own, [TEAM.name])
        own.train()
        assert gradient_steps(own, TEAM.name) == 12  # 600 rows in minibatches of 100, two epochs
    finally:
        own.stop()


def test_the_learning_rate_follows_its_schedule_over_env_steps(algo):  # `algo`: Ray is up
    run = RunConfig(**{**RUN.model_dump(), "ppo": {**RUN.ppo.model_dump(), "lr_schedule": [[0, 0.01], [600, 0.001]]}})
    plan = MatchPlan([{"attacker": ATTACKER.name}], [[SCRIPTED_TEAM.modules()]], [[1.0]], seed=0)
    own = build_config(run, [ATTACKER, SCRIPTED_TEAM], plan).build_algo()
    try:
        set_trainable(own, [ATTACKER.name])
        rates = []
        for _ in range(3):
            learner = own.train()["learners"][ATTACKER.name]
            rates.append(learner["default_optimizer_learning_rate"])
        # Set after each update from the env steps sampled so far (300 per iteration);
        # float32 schedule values: 1e-9.
        np.testing.assert_allclose(rates, [0.0055, 0.001, 0.001], rtol=0, atol=1e-9)
    finally:
        own.stop()


@contextlib.contextmanager
def changed_settings(module, **changes):
    """``module`` with its settings (``ActorCriticSettings``) changed as given, then as it was."""
    before = module.settings
    module.settings = before.model_copy(update=changes)
    try:
        yield
    finally:
        module.settings = before


def training_data_with_setting(algo, key, value, module_id=TEAM.name):
    """One play of the attacker and the team learning; its training data as the ``module_id``
    module (by default the team's) is configured, and with its setting ``key`` set to ``value``."""
    set_trainable(algo, [ATTACKER.name, TEAM.name])
    runner = algo.env_runner
    runner._reset_all()
    _, rows, t = runner._play(40, None, True, False)
    plain = runner._training_data(rows, t)
    with changed_settings(runner.module[module_id], **{key: value}):
        changed = runner._training_data(rows, t)
    return runner, rows, t, plain, changed


@pytest.mark.parametrize(("agent", "distance_of"), [("targeter", terminal_distance), ("defender", interception_distance)])
def test_a_team_agents_shaping_reaches_its_rows_and_no_others(algo, agent, distance_of):
    # `ppo.targeter_shaping`, `ppo.defender_shaping`: only that agent's rewards are shaped
    # (the other team agent's and the attacker's stay as they were).
    runner, rows, t, plain, shaped = training_data_with_setting(algo, f"{agent}_shaping", 3.0)
    np.testing.assert_array_equal(shaped[ATTACKER.name][Postprocessing.ADVANTAGES], plain[ATTACKER.name][Postprocessing.ADVANTAGES])
    # The team's columns hold T's rows, then D's. GAE is linear in the rewards, so the
    # shaping adds GAE of the shaping rewards alone (values 0) to that agent's advantages.
    gamma, lambda_ = RUN.ppo.discount("team")
    index = runner.rollout.module_ids.index(TEAM.name)
    played = rows.modules[:t, :, AGENTS.index(agent)] == index
    ended = (rows.outcome[:t] != int(Outcome.RUNNING)).astype(float)
    obs = rows.observations[agent][: t + 1]
    potentials = -3.0 * distance_of(runner.games.core.config, obs[:, :, -GLOBAL_STATE_SIZE:])
    zeros = np.zeros(ended.shape)
    added, _ = gae(potential_shaping(potentials, ended, gamma), zeros, zeros[0], ended, gamma, lambda_)
    targeter_rows = int((rows.modules[:t, :, 1] == index).sum())
    assert 0 < targeter_rows < len(plain[TEAM.name][Columns.OBS])
    difference = shaped[TEAM.name][Postprocessing.ADVANTAGES] - plain[TEAM.name][Postprocessing.ADVANTAGES]
    shaped_rows, other_rows = (slice(None, targeter_rows), slice(targeter_rows, None))[:: 1 if agent == "targeter" else -1]
    # float32 columns of advantages of size ~10: rounding ~1e-6.
    np.testing.assert_allclose(difference[shaped_rows], added[played], rtol=0, atol=1e-5)
    np.testing.assert_array_equal(difference[other_rows], 0.0)


def test_the_attackers_win_reward_is_paid_on_the_last_step_of_each_game(algo):
    # `ppo.attacker_win_reward`: +R on the step of each game the attacker won, -R on each it lost.
    runner, rows, t, plain, rewarded = training_data_with_setting(algo, "attacker_win_reward", 50.0, ATTACKER.name)
    np.testing.assert_array_equal(rewarded[TEAM.name][Postprocessing.ADVANTAGES], plain[TEAM.name][Postprocessing.ADVANTAGES])
    ended = rows.outcome[:t] != int(Outcome.RUNNING)
    won = np.isin(rows.outcome[:t], [int(o) for o in Outcome if o.attacker_wins])
    assert (ended & won).any() and (ended & ~won).any()  # both kinds of ending are in the rows
    gamma, lambda_ = RUN.ppo.discount("attacker")
    played = rows.modules[:t, :, 0] == runner.rollout.module_ids.index(ATTACKER.name)
    zeros = np.zeros(ended.shape)
    bonus = np.where(ended, np.where(won, 50.0, -50.0), 0.0)
    added, _ = gae(bonus, zeros, zeros[0], ended.astype(float), gamma, lambda_)
    difference = rewarded[ATTACKER.name][Postprocessing.ADVANTAGES] - plain[ATTACKER.name][Postprocessing.ADVANTAGES]
    # float32 columns of advantages of size ~50: rounding ~4e-6.
    np.testing.assert_allclose(difference, added[played], rtol=0, atol=2e-5)


def test_the_attackers_win_reward_goes_to_the_listed_reward_methods_only():
    # `ppo.attacker_win_reward_methods`: a league of methods 1-3 may pay it to methods 2 and 3 only.
    ppo = {**RUN.ppo.model_dump(), "attacker_win_reward": 70.0}
    for methods, paid in ((None, [70.0, 70.0, 70.0]), ([2, 3], [0.0, 70.0, 70.0])):
        run = RunConfig(**{**RUN.model_dump(), "ppo": {**ppo, "attacker_win_reward_methods": methods}})
        assert [learner_settings(run, "attacker", m).attacker_win_reward for m in (1, 2, 3)] == paid
        assert learner_settings(run, "team").attacker_win_reward == 0.0


def test_a_shared_team_reward_pays_t_and_d_the_sum_of_both(algo):
    # `ppo.team_reward: shared`: T's rows learn from r_T + r_D, D's rows too; the attacker's stay.
    runner, rows, t, own, shared = training_data_with_setting(algo, "team_reward", "shared")
    np.testing.assert_array_equal(shared[ATTACKER.name][Postprocessing.ADVANTAGES], own[ATTACKER.name][Postprocessing.ADVANTAGES])
    # GAE is linear in the rewards: T's advantages gain the GAE of D's rewards alone (values
    # 0), D's gain that of T's. The team's columns hold T's rows, then D's.
    gamma, lambda_ = RUN.ppo.discount("team")
    index = runner.rollout.module_ids.index(TEAM.name)
    played = rows.modules[:t, :, 1] == index  # T and D are played by the same module in every game
    ended = (rows.outcome[:t] != int(Outcome.RUNNING)).astype(float)
    zeros = np.zeros(ended.shape)
    from_d, _ = gae(rows.rewards["defender"][:t], zeros, zeros[0], ended, gamma, lambda_)
    from_t, _ = gae(rows.rewards["targeter"][:t], zeros, zeros[0], ended, gamma, lambda_)
    targeter_rows = int(played.sum())
    assert 0 < targeter_rows < len(own[TEAM.name][Columns.OBS])
    difference = shared[TEAM.name][Postprocessing.ADVANTAGES] - own[TEAM.name][Postprocessing.ADVANTAGES]
    # float32 columns of advantages of size ~1: rounding ~1e-7.
    np.testing.assert_allclose(difference[:targeter_rows], from_d[played], rtol=0, atol=1e-6)
    np.testing.assert_allclose(difference[targeter_rows:], from_t[played], rtol=0, atol=1e-6)


def test_frozen_players_play_their_mean_unless_they_explore(algo):
    # `league.frozen_players_explore: false`: a frozen module acts on its policy's mean while
    # the trained one keeps sampling.
    set_trainable(algo, [TEAM.name])
    runner = algo.env_runner
    attacker = runner.module[ATTACKER.name]
    for explore_when_frozen in (True, False):
        with changed_settings(attacker, explore_when_frozen=explore_when_frozen):
            runner._reset_all()
            _, rows, t = runner._play(10, None, True, False, episodes=False)
        # The means recomputed step by step over the same rows as the runner's forward pass (all
        # games' attackers): a matmul over other shapes may take other kernels and round otherwise.
        with torch.no_grad():
            means = np.stack([attacker.deterministic_action(torch.from_numpy(rows.observations["attacker"][s])).numpy() for s in range(t)])
        team = runner.module[TEAM.name]
        with torch.no_grad():
            team_means = team.deterministic_action(torch.from_numpy(rows.observations["targeter"][:t])).numpy()
        assert not np.allclose(rows.actions["targeter"][:t], team_means)
        if explore_when_frozen:
            assert not np.allclose(rows.actions["attacker"][:t], means)
        else:
            np.testing.assert_array_equal(rows.actions["attacker"][:t], means)


@pytest.mark.parametrize("epochs, shuffle", [(3, True), (1, True), (2, False)])
def test_minibatch_rows_are_rllibs_minibatches(epochs, shuffle):
    # Two modules of different lengths, neither a multiple of the minibatch size: minibatches
    # that wrap around, and the shorter module passed over more often than `epochs`.
    lengths = {"team": 23, "attacker": 10}
    batch = MultiAgentBatch({m: SampleBatch({"row": np.arange(n)}) for m, n in lengths.items()}, env_steps=10)
    np.random.seed(7)
    rllib = [
        {m: np.asarray(b["row"]) for m, b in minibatch.policy_batches.items()}
        for minibatch in MiniBatchCyclicIterator(
            batch, num_epochs=epochs, minibatch_size=4, shuffle_batch_per_epoch=shuffle
        )
    ]
    np.random.seed(7)
    ours = list(minibatch_rows(lengths, 4, epochs, shuffle))
    assert len(ours) == len(rllib) == -(-23 * epochs // 4)  # the longer module's passes decide
    for mine, theirs in zip(ours, rllib):
        assert mine.keys() == theirs.keys()
        for m in mine:
            np.testing.assert_array_equal(mine[m], theirs[m])
    np.random.seed(7)
    list(MiniBatchCyclicIterator(batch, num_epochs=epochs, minibatch_size=4, shuffle_batch_per_epoch=shuffle))
    after_rllib = np.random.random()
    np.random.seed(7)
    list(minibatch_rows(lengths, 4, epochs, shuffle))
    assert np.random.random() == after_rllib  # the same draws: what follows is unchanged too


def one_update(learner, batch, start, update):
    """``update`` (ours or RLlib's) of ``batch`` from the Learner state ``start``: the trained
    modules' weights after it and the results it reports."""
    state = copy.deepcopy(start["state"])  # the restored optimizer keeps the arrays it is given as its tensors
    learner.set_state(state)  # optimizer, metrics, weights sequence number
    learner.module.set_state(state["rl_module"])  # (`set_state` skips weights older than the Learner's)
    for module_id, coeff in start["kl_coeffs"].items():  # PPO's KL coefficient lives outside the state
        learner.curr_kl_coeffs_per_module[module_id].data.fill_(coeff)
    np.random.seed(11)  # RLlib shuffles with NumPy's global generator
    own = MultiAgentBatch({m: SampleBatch(dict(b)) for m, b in batch.policy_batches.items()}, batch.env_steps())
    results = update(
        learner, batch=own, timesteps={NUM_ENV_STEPS_SAMPLED_LIFETIME: 0}, num_epochs=3, minibatch_size=128,
        shuffle_batch_per_epoch=True,
    )
    weights = {
        m: {k: v.numpy().copy() for k, v in learner.module[m].state_dict().items()} for m in batch.policy_batches
    }
    reported = {m: {k: stats.peek() for k, stats in values.items()} for m, values in results.items()}
    return weights, reported


def compare_updates(algo, corrupt=None):
    """Our Learner's update and RLlib's ``Learner.update`` of one batch of the attacker and the
    team (300 rows and a few hundred: minibatches of 128 wrap around), from the same state
    (after one update of a first batch: Adam has moments, the weights sequence number is > 0)."""
    set_trainable(algo, [ATTACKER.name, TEAM.name])
    runner = algo.env_runner
    first, batch = (training_batch([runner.sample_training_data(300)], env_steps=300) for _ in range(2))
    if corrupt:
        corrupt(batch)

    def both(learner):
        one_update(learner, first, {"state": learner.get_state(), "kl_coeffs": {}}, type(learner).update)
        start = {
            "state": copy.deepcopy(learner.get_state()),  # (the optimizer's state shares the live tensors' memory)
            "kl_coeffs": {m: learner.curr_kl_coeffs_per_module[m].item() for m in batch.policy_batches},
        }
        ours = one_update(learner, batch, start, type(learner).update)
        return ours, one_update(learner, batch, start, PPOTorchLearner.update)

    [call] = algo.learner_group.foreach_learner(both)
    return call.get()


def test_our_update_trains_as_rllibs_update(algo):
    (ours, ours_reported), (rllib, rllib_reported) = compare_updates(algo)
    # The same float32 operations in the same order (minibatch rows, loss, clipping
    # coefficient, Adam's foreach passes are its per-tensor arithmetic): equal to the bit.
    for module_id in (ATTACKER.name, TEAM.name):
        for name, weight in rllib[module_id].items():
            np.testing.assert_array_equal(ours[module_id][name], weight, err_msg=f"{module_id} {name}")
    assert ours_reported.keys() == rllib_reported.keys()
    for module_id in (ATTACKER.name, TEAM.name, ALL_MODULES):
        theirs = {k: v for k, v in rllib_reported[module_id].items() if "throughput" not in k}  # per second
        np.testing.assert_equal({k: ours_reported[module_id].get(k) for k in theirs}, theirs, err_msg=module_id)
    team, attacker = ours_reported[TEAM.name], ours_reported[ATTACKER.name]
    # Both modules in every minibatch, until each row was passed 3 times (the attacker has 300).
    assert team["num_module_steps_trained"] == attacker["num_module_steps_trained"] >= 3 * 300
    assert {"policy_loss", "vf_loss", "entropy", "mean_kl_loss", "curr_kl_coeff", "total_loss"} <= team.keys()


def test_non_finite_gradients_are_handled_as_rllib_does(algo):
    # A NaN advantage makes every gradient NaN: RLlib zeroes them and still steps Adam.
    def nan_advantage(batch):
        batch.policy_batches[TEAM.name][Postprocessing.ADVANTAGES][5] = np.nan

    (ours, _), (rllib, _) = compare_updates(algo, nan_advantage)
    assert all(np.isfinite(w).all() for w in rllib[TEAM.name].values())
    for module_id in (ATTACKER.name, TEAM.name):
        for name, weight in rllib[module_id].items():
            np.testing.assert_array_equal(ours[module_id][name], weight, err_msg=f"{module_id} {name}")


def test_our_update_without_the_kl_term_trains_as_rllibs_update(algo):
    # Every shipped config keeps RLlib's default, PPO's KL term; without it (`use_kl_loss`
    # off) the loss has no KL term, the reported KL is 0 and the KL coefficient stays.
    def use_kl_loss(on):
        def set_it(learner):
            learner.config.use_kl_loss = on

        [call.get() for call in algo.learner_group.foreach_learner(set_it)]

    use_kl_loss(False)
    try:
        (ours, ours_reported), (rllib, rllib_reported) = compare_updates(algo)
    finally:
        use_kl_loss(True)
    for module_id in (ATTACKER.name, TEAM.name):  # the same operations: equal to the bit
        for name, weight in rllib[module_id].items():
            np.testing.assert_array_equal(ours[module_id][name], weight, err_msg=f"{module_id} {name}")
    assert ours_reported.keys() == rllib_reported.keys()
    for module_id in (ATTACKER.name, TEAM.name, ALL_MODULES):
        theirs = {k: v for k, v in rllib_reported[module_id].items() if "throughput" not in k}
        np.testing.assert_equal({k: ours_reported[module_id].get(k) for k in theirs}, theirs, err_msg=module_id)
    assert ours_reported[TEAM.name]["mean_kl_loss"] == 0.0


def test_a_team_only_width_builds_the_team_wider_and_the_attacker_as_before():
    run = RUN.model_copy(update={"ppo": RUN.ppo.model_copy(update={"team_hidden": [32, 8]})})
    modules = {side: learner_spec(run, side, 2 if side == "attacker" else None).build() for side in ("attacker", "team")}
    widths = {
        (side, net): [layer.out_features for layer in getattr(module, net) if isinstance(layer, torch.nn.Linear)]
        for side, module in modules.items() for net in ("pi", "vf")
    }
    # hidden [16] and team_hidden, then the mean of the 2 actions (policy) or the value
    assert widths == {("attacker", "pi"): [16, 2], ("attacker", "vf"): [16, 1], ("team", "pi"): [32, 8, 2], ("team", "vf"): [32, 8, 1]}


def compare_bf16_update(algo, monkeypatch, native: bool):
    """``compare_updates`` with the team module asking for bf16 on a CPU that has it (``native``)
    or not; also the dtypes the Linear layers of each module output inside our Learner's loss
    (``ppo_loss``, which RLlib's own update does not call), by module id."""
    monkeypatch.setattr("league.rllib.compat.native_bf16", lambda: native)  # the local Learner runs in this process
    def module_ids_by_object(learner):
        return {id(learner.module[m]): m for m in learner.module.keys()}

    [call] = algo.learner_group.foreach_learner(module_ids_by_object)
    module_ids, dtypes = call.get(), {}
    original = learner_module.ppo_loss

    def recording(module, batch, c, bf16=False):
        seen = dtypes.setdefault(module_ids[id(module)], set())
        hooks = [
            layer.register_forward_hook(lambda _layer, _inputs, out: seen.add(out.dtype))
            for layer in module.modules() if isinstance(layer, torch.nn.Linear)
        ]
        try:
            return original(module, batch, c, bf16)
        finally:
            for hook in hooks:
                hook.remove()

    monkeypatch.setattr(learner_module, "ppo_loss", recording)

    def ask(on):
        def set_it(learner):
            module = learner.module[TEAM.name]
            module.settings = module.settings.model_copy(update={"bf16": on})

        [call.get() for call in algo.learner_group.foreach_learner(set_it)]

    ask(True)
    try:
        return compare_updates(algo), dtypes
    finally:
        ask(False)


def test_bf16_falls_back_to_float32_where_the_cpu_has_no_native_bf16(algo, monkeypatch):
    ((ours, _), (rllib, _)), dtypes = compare_bf16_update(algo, monkeypatch, native=False)
    assert dtypes == {ATTACKER.name: {torch.float32}, TEAM.name: {torch.float32}}
    for module_id in (ATTACKER.name, TEAM.name):  # float32 throughout: RLlib's update to the bit
        for name, weight in rllib[module_id].items():
            np.testing.assert_array_equal(ours[module_id][name], weight, err_msg=f"{module_id} {name}")


def test_bf16_where_native_runs_the_team_networks_in_bf16_and_stays_near_float32(algo, monkeypatch):
    # (Forced on: torch's autocast emulates bf16 where the CPU has none, the same rounding.)
    ((ours, reported), (rllib, _)), dtypes = compare_bf16_update(algo, monkeypatch, native=True)
    # Every layer of the team's networks computes in bf16 in our update; the attacker did not ask.
    assert dtypes == {ATTACKER.name: {torch.float32}, TEAM.name: {torch.bfloat16}}
    for name, weight in rllib[ATTACKER.name].items():  # float32: RLlib's update to the bit
        np.testing.assert_array_equal(ours[ATTACKER.name][name], weight, err_msg=name)
    # The team's weights after the bf16 update against RLlib's float32 one, from the same start.
    differences = {name: np.abs(ours[TEAM.name][name] - weight).max() for name, weight in rllib[TEAM.name].items()}
    largest = max(np.abs(weight).max() for weight in rllib[TEAM.name].values())
    # Above float32's rounding: ten float32 ulps of the largest weight (here ~1e-6).
    assert max(differences.values()) > 10 * np.finfo(np.float32).eps * largest, differences
    # Below bf16's: each Adam step moves a weight by about lr; bf16's rounding of the forward pass
    # (2^-8 relative) changes it by a few 2^-8 of that, so by at most lr / 16 per step (~1.9e-4
    # here; ~2e-5 seen). Weights kept in bf16 would lose the steps (their ulp ~4e-3 > lr).
    steps = reported[TEAM.name]["num_module_steps_trained"] / 128
    assert max(differences.values()) < RUN.ppo.lr / 16 * steps, differences


def test_the_compiled_loss_trains_as_rllibs_update_up_to_float32_rounding(algo):
    """``ppo.compile_loss``: our update with its loss under ``torch.compile`` against RLlib's, from the same state."""
    def compile_loss(on):
        def set_it(learner):
            learner.config.learner_config_dict[COMPILED_LOSS] = on

        [call.get() for call in algo.learner_group.foreach_learner(set_it)]

    graphs = torch._dynamo.utils.counters["stats"]["unique_graphs"]  # the local Learner runs in this process
    compile_loss(True)
    try:
        (ours, _), (rllib, _) = compare_updates(algo)
    finally:
        compile_loss(False)
    assert torch._dynamo.utils.counters["stats"]["unique_graphs"] > graphs  # the loss ran compiled
    for module_id in (ATTACKER.name, TEAM.name):
        differences = {name: np.abs(ours[module_id][name] - weight).max() for name, weight in rllib[module_id].items()}
        largest = max(np.abs(weight).max() for weight in rllib[module_id].values())
        # The compiled kernels fuse the loss's operations and sum in another order: float32 rounding,
        # carried through 2 updates of 3 epochs; within ten float32 ulps of the largest weight (< 1 seen).
        assert max(differences.values()) <= 10 * np.finfo(np.float32).eps * largest, (module_id, differences)

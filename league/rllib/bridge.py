"""Where the league meets RLlib: the one module the rest of the code calls the adapter through.

Build the algorithm (``build_config``: module specs, the match plan as RLlib's mapping,
the league's algorithm, learner, env runner and callbacks), drive its env runners (match
plans, seeds, games in flight), move weights (snapshots, frozen players, saved modules),
read ``train()`` results and load checkpoints (only here and in ``league.rllib.algorithm``).
RLlib's private attributes are touched only by ``league.rllib.compat``.

The league decides each episode's opponents itself (``league.core.match_plan.MatchPlan``);
the outcomes reach the driver through RLlib's metrics (``callbacks.OutcomeRecorder``,
``episode_outcomes``).
"""

from __future__ import annotations

import errno

import functools
import logging
import warnings
from pathlib import Path
from typing import Any

import torch

from envs.agents import AGENTS
from envs.observations import observation_size
from envs.rllib_env import TargetDefenseMultiAgentEnv, policy_input_space
from envs.single import action_space
from league.config import RunConfig
from league.core.match_plan import MatchPlan
from league.core.players import NewPlayer, Player
from league.rllib.algorithm import COMPILED_LOSS, MINIBATCH_SIZES, NUM_EPOCHS, RESIDUAL_PENALTIES, RESIDUAL_PENALTY_GATED, SAMPLE_AHEAD, FaultTolerantPPO, LeaguePPO, with_env_runner_fault_tolerance
from league.rllib.callbacks import AttackerRewardByMethod, OutcomeRecorder
from league.rllib.env_runner import BatchedEnvRunner, SeededEnvRunner, seed_iteration
from league.rllib import compat
from league.rllib.learner import LeaguePPOLearner
from league.rllib.module_settings import ActorCriticSettings, ScriptedSettings
from league.rllib.modules import ActorCriticModule, ScriptedModule
from league.rllib.runner_metrics import OUTCOMES_KEY, SEPARATOR
from league.rollout.training_reward import TrainingPay
from ray.rllib.algorithms.algorithm import Algorithm
from ray.rllib.algorithms.ppo import PPO, PPOConfig
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec
from ray.rllib.utils.metrics import (
    ENV_RUNNER_RESULTS,
    EPISODE_MODULE_RETURN_MEAN,
    LEARNER_RESULTS,
    NUM_ENV_STEPS_SAMPLED_LIFETIME,
    NUM_MODULE_STEPS_SAMPLED,
)


class _NotTheNews(logging.Filter):
    """Drops RLlib's banner on every config built ("You are running PPO on the new API stack!")."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "on the new API stack" not in record.getMessage()


logging.getLogger("ray.rllib.algorithms.algorithm_config").addFilter(_NotTheNews())
# RLlib registers the env with gymnasium anew for every algorithm built; gymnasium then warns, in colour.
warnings.filterwarnings("ignore", message=r".*Overriding environment .* already in registry")


def env_config(run: RunConfig) -> dict[str, Any]:
    return {**run.game.model_dump(), "with_global_state": True}


def actor_inputs(run: RunConfig, agent: str) -> int:
    """Length of the agent's own observation (the global state follows it)."""
    return observation_size(run.game, AGENTS.index(agent))


def learner_settings(run: RunConfig, side: str, reward_method: int | None = None) -> ActorCriticSettings:
    """What the ``side`` learner's module is built with and how it is paid (``TrainingPay.of``)."""
    agent = "attacker" if side == "attacker" else "targeter"
    team = side == "team"
    return ActorCriticSettings(
        actor_inputs=actor_inputs(run, agent),
        critic="global" if team else "local",
        hidden=run.ppo.hidden_of(side),
        prior=run.ppo.team_prior if team else run.ppo.attacker_prior,
        heading_cosines=run.ppo.attacker_heading_cosines and not team,
        scripted_turns=run.ppo.attacker_scripted_turns and not team,
        game=run.game,
        bf16=run.ppo.bf16,
        explore_when_frozen=run.league.frozen_players_explore,
        **TrainingPay.of(run, side, reward_method).model_dump(),
    )


def learner_spec(run: RunConfig, side: str, reward_method: int | None = None) -> RLModuleSpec:
    agent = "attacker" if side == "attacker" else "targeter"
    return RLModuleSpec(
        module_class=ActorCriticModule,
        observation_space=policy_input_space(run.game, agent),
        action_space=action_space(run.game),
        model_config=learner_settings(run, side, reward_method).as_model_config(),
    )


def learner_computes_in_bf16(run: RunConfig) -> bool:
    """Whether this process's learner runs its networks in bfloat16 (``PPOSettings.bf16``)."""
    return run.ppo.bf16 and compat.native_bf16()


def learner_compiles_loss(run: RunConfig) -> bool:
    """Whether this process's learner runs its loss compiled (``PPOSettings.compile_loss``)."""
    return run.ppo.compile_loss and compat.inductor_compiler_found()


def scripted_spec(run: RunConfig, agent: str, name: str) -> RLModuleSpec:
    return RLModuleSpec(
        module_class=ScriptedModule,
        observation_space=policy_input_space(run.game, agent),
        action_space=action_space(run.game),
        model_config=ScriptedSettings(
            agent=agent, name=name, game=run.game, actor_inputs=actor_inputs(run, agent)
        ).as_model_config(),
    )


def player_specs(run: RunConfig, player: Player) -> dict[str, RLModuleSpec]:
    """Module id -> spec of every module the player needs."""
    if player.kind != "scripted":
        return {player.name: learner_spec(run, player.side, player.reward_method)}
    names = player.scripted_players()
    return {module: scripted_spec(run, agent, names[agent]) for agent, module in player.modules().items()}


# ---------------------------------------------------------------- train() results
def episode_outcomes(result: dict[str, Any]) -> list[tuple[tuple[str, str, str], str, int]]:
    """``((attacker, targeter, defender modules), outcome, count)`` of one ``train()`` result."""
    counts = result.get(ENV_RUNNER_RESULTS, {}).get(OUTCOMES_KEY, {})
    rows = []
    for modules, outcomes in counts.items():
        for outcome, count in outcomes.items():
            if count == count and count > 0:  # keys of modules that did not play this time are NaN
                rows.append((tuple(modules.split(SEPARATOR)), outcome, int(count)))
    return rows


def module_returns(result: dict[str, Any], modules: list[str]) -> dict[str, float]:
    """Mean episode return of each of ``modules`` that finished episodes this iteration."""
    means = result.get(ENV_RUNNER_RESULTS, {}).get(EPISODE_MODULE_RETURN_MEAN, {})
    return {m: float(means[m]) for m in modules if m in means and means[m] == means[m]}


def env_runner_health(algo: Algorithm) -> tuple[int, int, int]:
    """``(healthy, total, restarts)`` of the remote env runners (all 0 when sampling in the driver)."""
    group = algo.env_runner_group
    return group.num_healthy_remote_env_runners(), group.num_remote_env_runners(), group.num_remote_worker_restarts()


def sampled_env_steps(result: dict[str, Any]) -> int:
    return int(result.get(ENV_RUNNER_RESULTS, {}).get(NUM_ENV_STEPS_SAMPLED_LIFETIME, 0))


def learner_env_steps(result: dict[str, Any], learners: list[Player]) -> dict[str, int]:
    """Env steps of the games each learner played in this ``train()``, from the runners' exact
    per-module counts: a module's agent steps over the agents it plays in a game (the team's
    module plays T and D)."""
    played = result.get(ENV_RUNNER_RESULTS, {}).get(NUM_MODULE_STEPS_SAMPLED, {})
    steps = {}
    for learner in learners:
        count = played.get(learner.name, 0)
        steps[learner.name] = int(count) // len(learner.modules()) if count == count else 0  # NaN: idle this time
    return steps


def _runner_threads(threads: int, env_runner: Any = None, **kwargs: Any) -> None:
    """``on_environment_created`` callback: the torch threads of an env runner's process
    (RLlib leaves torch's default, all cores)."""
    torch.set_num_threads(threads)


# ---------------------------------------------------------------- the algorithm and its runners
def take_learning_seconds(algo: Algorithm) -> float:
    """Wall time the Learner spent updating since the last call (the slowest Learner's, if several)."""
    results = algo.learner_group.foreach_learner(lambda learner: learner.take_update_seconds())
    return max((r.get() for r in results if r.ok), default=0.0)


def build_config(run: RunConfig, players: list[Player], plan: MatchPlan) -> PPOConfig:
    """PPO over every module the ``players`` need; only learners are ever trained."""
    specs: dict[str, RLModuleSpec] = {}
    for player in players:
        specs.update(player_specs(run, player))
    res, ppo = run.resources, run.ppo
    config = (
        PPOConfig(algo_class=LeaguePPO if res.sampler == "fast" else FaultTolerantPPO)
        .environment(env=TargetDefenseMultiAgentEnv, env_config=env_config(run), normalize_actions=False, clip_actions=False)
        .env_runners(
            num_env_runners=res.num_env_runners,
            num_envs_per_env_runner=res.num_envs_per_env_runner,
            num_cpus_per_env_runner=res.num_cpus_per_env_runner,
            custom_resources_per_env_runner=res.custom_resources_per_env_runner,
            rollout_fragment_length="auto",
            env_runner_cls=SeededEnvRunner if res.sampler == "standard" else BatchedEnvRunner,
        )
        .learners(
            num_learners=0,
            learner_config_dict={
                MINIBATCH_SIZES: {p.name: ppo.minibatch(p.side) for p in players if p.trains},
                NUM_EPOCHS: {p.name: ppo.epochs(p.side) for p in players if p.trains},
                SAMPLE_AHEAD: res.sample_ahead,
                COMPILED_LOSS: learner_compiles_loss(run),
                RESIDUAL_PENALTIES: {p.name: ppo.attacker_residual_penalty for p in players if p.trains and p.side == "attacker"},
                RESIDUAL_PENALTY_GATED: ppo.attacker_residual_penalty_gate != "always",
            },
        )
        .multi_agent(
            policies=list(specs),
            policy_mapping_fn=plan,
            policies_to_train=[p.name for p in players if p.trains],
        )
        .rl_module(rl_module_spec=MultiRLModuleSpec(rl_module_specs=specs))
        .training(
            lr=ppo.lr if ppo.lr_schedule is None else [list(point) for point in ppo.lr_schedule],
            gamma=ppo.gamma,
            lambda_=ppo.lambda_,
            clip_param=ppo.clip_param,
            entropy_coeff=ppo.entropy_coeff,
            vf_loss_coeff=ppo.vf_loss_coeff,
            grad_clip=ppo.grad_clip,
            train_batch_size_per_learner=ppo.train_batch_size,
            minibatch_size=ppo.minibatch_size,
            num_epochs=ppo.num_epochs,
            vf_clip_param=float("inf"),
            learner_class=LeaguePPOLearner,
            learner_connector=lambda observation_space, action_space: AttackerRewardByMethod(),
        )
        .callbacks(
            OutcomeRecorder,
            on_environment_created=functools.partial(_runner_threads, res.threads_for(res.num_cpus_per_env_runner)),
        )
        .debugging(seed=run.seed, log_level="ERROR")
        .reporting(metrics_num_episodes_for_smoothing=100)
    )
    return with_env_runner_fault_tolerance(config)


def set_match_plan(algo: Algorithm, plan: MatchPlan) -> None:
    """Send a new mapping to every EnvRunner (ongoing episodes keep their old mapping)."""
    algo.env_runner_group.foreach_env_runner(
        lambda runner: runner.config.multi_agent(policy_mapping_fn=plan), local_env_runner=True
    )


def begin_iteration(algo: Algorithm, seed: int, iteration: int) -> None:
    """Seed every env runner's (and the driver's) generators for ``iteration`` of a run seeded
    ``seed`` (``BatchedEnvRunner.begin_iteration``): an iteration then depends only on the
    checkpointed state it starts from, not on how the process got there."""

    def begin(runner: Any) -> None:
        if isinstance(runner, BatchedEnvRunner):
            runner.begin_iteration(seed, iteration)
        else:  # RLlib's own runner (`sampler: standard`) names its episodes at random all the same
            seed_iteration(runner, seed, iteration)

    algo.env_runner_group.foreach_env_runner(begin, local_env_runner=True)


def games_in_flight(algo: Algorithm) -> dict[int, bytes]:
    """Each fast or batched env runner's games in flight (``BatchedEnvRunner.games_in_flight``), by worker index."""
    states = algo.env_runner_group.foreach_env_runner(
        lambda runner: (runner.worker_index, runner.games_in_flight()) if isinstance(runner, BatchedEnvRunner) else None,
        local_env_runner=True,
    )
    return dict(state for state in states if state is not None)


def restart_games(algo: Algorithm) -> None:
    """Every fast or batched env runner drops its games in flight (``BatchedEnvRunner.restart_games``),
    and the driver the batch sampled ahead (``resources.sample_ahead``): a phase learns from its own games only."""
    _on_batched_runners(algo, lambda runner: runner.restart_games())
    if isinstance(algo, LeaguePPO):
        algo.drop_sampled_ahead()


def batch_sampled_ahead(algo: Algorithm) -> dict[str, Any] | None:
    """The batch sampled ahead and not yet learned (``resources.sample_ahead``), which a checkpoint keeps; None: none."""
    return algo.sampled_ahead if isinstance(algo, LeaguePPO) else None


def restore_batch_sampled_ahead(algo: Algorithm, batch: dict[str, Any]) -> None:
    """Give the algorithm back its batch sampled ahead (``batch_sampled_ahead``): the next iteration learns from it."""
    algo.sampled_ahead = batch


def _on_batched_runners(algo: Algorithm, call: Any) -> None:
    """``call(runner)`` on every fast or batched env runner, the driver's included."""
    algo.env_runner_group.foreach_env_runner(
        lambda runner: call(runner) if isinstance(runner, BatchedEnvRunner) else None, local_env_runner=True
    )


def restore_games(algo: Algorithm, states: dict[int, bytes]) -> None:
    """Hand each env runner its games in flight from ``games_in_flight`` (a runner without any starts anew)."""

    _on_batched_runners(
        algo, lambda runner: runner.restore_games(states[runner.worker_index]) if runner.worker_index in states else None
    )


def set_trainable(algo: Algorithm, module_ids: list[str]) -> None:
    """Train only ``module_ids`` from now on (the learning side of the phase)."""
    algo.learner_group.foreach_learner(lambda learner: learner.config.multi_agent(policies_to_train=module_ids))
    algo.env_runner_group.foreach_env_runner(
        lambda runner: runner.config.multi_agent(policies_to_train=module_ids), local_env_runner=True
    )


def add_snapshot(algo: Algorithm, run: RunConfig, snapshot: Player, source_module: str) -> None:
    """Add a frozen copy of ``source_module`` as ``snapshot.name`` to learners and EnvRunners."""
    algo.add_module(module_id=snapshot.name, module_spec=learner_spec(run, snapshot.side, snapshot.reward_method))
    weights = algo.learner_group.get_weights(module_ids=[source_module])[source_module]
    algo.learner_group.set_weights({snapshot.name: weights})
    # Set directly: a weight sync would be skipped, the EnvRunners already hold the
    # learner group's current weights sequence number.
    algo.env_runner_group.foreach_env_runner(
        lambda runner: runner.module[snapshot.name].set_state(weights), local_env_runner=True
    )


def add_frozen_player(algo: Algorithm, run: RunConfig, player: NewPlayer, path: Path) -> None:
    """Add ``player``, trained outside this algorithm (a double-oracle best response), as a frozen
    module built as the run builds its side's learners, its weights the module saved at ``path``."""
    algo.add_module(module_id=player.name, module_spec=learner_spec(run, player.side, player.reward_method))
    load_frozen_module(algo, player.name, path)


def has_module(algo: Algorithm, module_id: str) -> bool:
    """Whether the algorithm's learner holds ``module_id`` (a restored checkpoint holds the modules it was saved with)."""
    return all(r.get() for r in algo.learner_group.foreach_learner(lambda learner: module_id in learner.module))


def restart_module(algo: Algorithm, module_id: str, source_module: str) -> None:
    """Give ``module_id`` the weights of ``source_module`` and a new optimizer state (Adam's
    moments and step count cleared): it trains on as if it were a new module with those weights."""
    weights = learner_weights(algo, source_module)
    algo.learner_group.set_weights({module_id: weights})

    def clear(learner: Any) -> None:
        for _, optimizer in learner.get_optimizers_for_module(module_id):
            optimizer.state.clear()

    algo.learner_group.foreach_learner(clear)
    algo.env_runner_group.foreach_env_runner(  # set directly, as in ``add_snapshot``
        lambda runner: runner.module[module_id].set_state(weights), local_env_runner=True
    )


def save_module(algo: Algorithm, module_id: str, path: Path) -> None:
    """Write one module (class, spaces, config and weights) for use without the algorithm."""
    module = algo.get_module(module_id)
    module.save_to_path(str(path))


def learner_weights(algo: Algorithm, module_id: str) -> dict[str, torch.Tensor]:
    return algo.learner_group.get_weights(module_ids=[module_id])[module_id]


def live_module(algo: Algorithm, run: RunConfig, learner: Player) -> torch.nn.Module:
    """A copy of ``learner``'s module with its weights as they are now, in eval mode (a learning-curve point)."""
    module = learner_spec(run, learner.side, learner.reward_method).build()
    module.set_state(learner_weights(algo, learner.name))
    module.eval()
    return module


# ---------------------------------------------------------------- checkpoints and results
def load_module(path: str | Path) -> torch.nn.Module:
    """A module saved by ``save_module``, in eval mode."""
    from ray.rllib.core.rl_module.rl_module import RLModule

    if not Path(path).is_dir():
        raise FileNotFoundError(errno.ENOENT, f"no saved module at {path}", str(path))
    for name in ("class_and_ctor_args.pkl", "module_state.pkl"):  # the files RLModule.from_checkpoint reads
        if not Path(path, name).is_file():
            raise FileNotFoundError(errno.ENOENT, f"no saved module at {path} ({name} missing)", str(Path(path, name)))
    module = RLModule.from_checkpoint(str(Path(path).resolve()))
    module.eval()
    return module


def restore_algorithm(path: str | Path) -> Algorithm:
    """The algorithm of a checkpoint, snapshot modules added at run time included, every env runner holding the
    learner's weights of every module.

    RLlib's restore (Ray 2.60) hands the remote env runners the local runner's state, its weights'
    sequence number included, but not its weights, then skips the weight sync as up to date: they
    went on sampling with the weights they were built with (the learners' priors, untrained
    snapshots) until the next update, and a resumed run was another run."""
    algo = Algorithm.from_checkpoint(str(path))
    weights = {m: w for m, w in algo.learner_group.get_weights().items() if w}  # scripted modules have none
    algo.env_runner_group.foreach_env_runner(
        lambda runner: [runner.module[m].set_state(w) for m, w in weights.items()], local_env_runner=False,
    )
    return algo


def learner_stats(result: dict[str, Any], modules: list[str]) -> dict[str, dict[str, Any]]:
    """The Learner's results (losses, entropy, KL, ...) of each of ``modules`` it trained in this ``train()``."""
    learners = result.get(LEARNER_RESULTS, {})
    return {m: dict(learners[m]) for m in modules if m in learners}


def load_frozen_module(algo: Algorithm, module_id: str, path: Path) -> None:
    """Set the weights of ``module_id`` (already in the algorithm) to the module saved at ``path``
    (``save_module``), in the learners and every EnvRunner: a frozen player of another run."""
    weights = load_module(path).get_state()
    algo.learner_group.set_weights({module_id: weights})
    algo.env_runner_group.foreach_env_runner(  # set directly, as in ``add_snapshot``
        lambda runner: runner.module[module_id].set_state(weights), local_env_runner=True
    )

"""The fast sampling path: an RLlib EnvRunner that steps all of its games as arrays.

RLlib's ``MultiAgentEnvRunner`` steps each sub-environment in a Python loop and runs
its connector pipelines on every step. ``BatchedEnvRunner`` keeps everything else of it
(the modules, weight and state sync, checkpoints, metrics, fault tolerance) and replaces
``sample()``: the games are played by ``league.rollout.games`` (one step of all N games is one
call of ``envs.vector_env`` and one forward pass per module over every (game, agent) it
plays); this class turns the rollout's rows into what RLlib wants. Episodes reach the Learner as
``MultiAgentEpisode`` chunks built from the arrays, with the observations, actions,
rewards, infos and model outputs of the standard path (``tests/rllib/test_batched_sampler.py``
plays both side by side).

Differences, all for speed:

* Episodes carry only the agents whose module is trained (the learning side); the
  Learner would drop the steps of scripted players and frozen snapshots anyway.
  ``episode.module_for`` still names every agent's module. (An episode in which no
  module is trained, as at a phase switch, carries all three agents.)
* Of the per-episode metrics (windows of the last 100 episodes) only the episodes
  that can still be in a window are logged at the end of each ``sample()`` call.
* The env-to-module and module-to-env connector pipelines are not run. The league uses
  RLlib's defaults, which only batch, sample from the action distribution and unbatch;
  a config with connectors of its own is refused.
* Of the episode callbacks only ``on_episode_end`` is called (and ``on_sample_end``).
* The agent-to-module mapping is asked with an ``EpisodeRef`` (the episode's id, all
  that the league's ``MatchPlan`` reads), once per agent when a game starts.

``sample_training_data`` is the fast path (``resources.sampler: fast``): the same play,
but no episode objects at all; PPO's columns, with advantages and value targets by GAE
over the arrays (``league.rollout.train_batch``), go straight to the Learner (``LeaguePPO``).
Finished games still log their metrics and outcome; no episode callback is called.
Scripted players act on the games' exact state (as in evaluation), not on the float32
global state that their RLModule decodes on the other paths.
"""

from __future__ import annotations

import math
import pickle
import random
import time
from collections import Counter, defaultdict
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from envs.agents import AGENTS, Outcome
from envs.observations import GLOBAL_STATE_SIZE, interception_distance, terminal_distance
from envs.vector_env import TargetDefenseVectorEnv
from league.core.payoff import attacker_won_games
from league.core.seeding import Purpose, stream, stream_seed
from league.rllib import compat
from league.rllib.modules import ActorCriticModule, ScriptedModule
from league.rollout.games import Policy, Rollout, Rows, ScriptedOnState
from league.rollout.train_batch import gae, potential_shaping
from ray.rllib.callbacks.utils import make_callback
from ray.rllib.core.columns import Columns
from ray.rllib.env.multi_agent_env_runner import MultiAgentEnvRunner
from ray.rllib.env.multi_agent_episode import MultiAgentEpisode
from ray.rllib.env.single_agent_episode import SingleAgentEpisode
from ray.rllib.evaluation.postprocessing import Postprocessing
from ray.rllib.utils.metrics import (
    EPISODE_AGENT_RETURN_MEAN,
    EPISODE_AGENT_STEPS,
    EPISODE_DURATION_SEC_MEAN,
    EPISODE_LEN_MAX,
    EPISODE_LEN_MEAN,
    EPISODE_LEN_MIN,
    EPISODE_MODULE_RETURN_MEAN,
    EPISODE_RETURN_MAX,
    EPISODE_RETURN_MEAN,
    EPISODE_RETURN_MIN,
    NUM_AGENT_STEPS_SAMPLED,
    NUM_AGENT_STEPS_SAMPLED_LIFETIME,
    NUM_ENV_STEPS_SAMPLED,
    NUM_ENV_STEPS_SAMPLED_LIFETIME,
    NUM_EPISODES,
    NUM_EPISODES_LIFETIME,
    NUM_MODULE_STEPS_SAMPLED,
    NUM_MODULE_STEPS_SAMPLED_LIFETIME,
    RLMODULE_INFERENCE_TIMER,
    SAMPLE_TIMER,
    WEIGHTS_SEQ_NO,
)

# The distance each team agent's potential-based shaping measures (T: to the terminal, D: to A).
SHAPED_DISTANCE = {"targeter": terminal_distance, "defender": interception_distance}

RESET_INFOS: dict[str, dict] = {agent: {} for agent in AGENTS}  # what a reset returns as infos
OUTCOMES_KEY = "league_outcomes"  # metrics key of the finished games by modules and outcome
SEPARATOR = "|"


@dataclass(frozen=True)
class EpisodeRef:
    """What this runner hands the agent-to-module mapping: the episode's id (``id_``)."""

    id_: str


class SeededEnvRunner(MultiAgentEnvRunner):
    """RLlib's runner with its games' starts drawn from the run's own stream for this runner.

    RLlib seeds runner ``w`` with ``seed + w`` and its game ``i`` with ``seed + w + i``, so runs
    of neighbouring seeds, and the runners of one run, would replay each other's starts.
    """

    def __init__(self, config: Any, **kwargs: Any):
        super().__init__(config=config, **kwargs)
        if self.config.seed is not None:
            compat.set_env_runner_seed(self, stream_seed(self.config.seed, Purpose.GAME_STARTS, self.worker_index))


class BatchedEnvRunner(SeededEnvRunner):
    """Samples ``num_envs_per_env_runner`` games of ``envs.vector_env`` at once.

    As the standard runner does (``batch_mode="truncate_episodes"``), episodes still
    running at the end of a ``sample()`` call are returned as chunks and continued in
    the next call.
    """

    def __init__(self, config: Any, **kwargs: Any):
        if compat.has_custom_connectors(config):
            raise ValueError("BatchedEnvRunner runs RLlib's default connectors only: use the standard sampler")
        self.games: TargetDefenseVectorEnv | None = None
        self.rollout: Rollout | None = None
        self._needs_seeded_reset = True
        self._restart_games = False  # `restart_games`: the next sample starts every game anew
        super().__init__(config=config, **kwargs)
        # Episodes are named by the iteration that started them and a count (``begin_iteration``),
        # not at random: the league's mapping draws each episode's match from its name.
        self._episode_prefix, self._episode_count = f"s{compat.env_runner_seed(self)}-w{self.worker_index}-", 0

    def make_env(self) -> None:
        # The standard sub-envs stay for what RLlib reads off them (spaces, callbacks);
        # the games are stepped in `self.games`.
        super().make_env()
        self.games = TargetDefenseVectorEnv(dict(self.config.env_config), self.num_envs)
        # The league's mapping (`MatchPlan`) reads only the episode's id: no episode object
        # is built per game (RLlib's ids are uuid4 hex strings too).
        self.rollout = Rollout(
            self.games,
            lambda agent, episode_id: self.config.policy_mapping_fn(agent, EpisodeRef(episode_id)),
            new_episode_id=self._new_episode_id,
        )
        env = self.env.envs[0].unwrapped
        self._spaces = (dict(env.observation_spaces), dict(env.action_spaces))
        # As the standard runner: a new env, or a sample by episode count, starts every game
        # anew from the seed; `force_reset` starts them anew where their generators are.
        self._needs_seeded_reset = True

    def _new_episode_id(self) -> str:
        self._episode_count += 1
        return f"{self._episode_prefix}{self._episode_count}"

    # ------------------------------------------------------------------ iterations
    def begin_iteration(self, seed: int, iteration: int) -> None:
        """Seed what this iteration's sampling draws from, by (run seed, iteration, worker index):
        torch's, NumPy's and Python's global generators (the actions explored; in the driver,
        also the Learner's minibatch shuffles) and the names of new episodes. The games' own
        generators go on from where they are: they travel with the games in flight
        (``games_in_flight``)."""
        seed_iteration(self, seed, iteration)
        self._episode_prefix, self._episode_count = f"i{iteration}-w{self.worker_index}-", 0

    def restart_games(self) -> None:
        """Drop the games in flight: the next ``sample`` starts every game anew (where the games'
        generators are). At a phase switch, so that no game of the side that stopped learning
        is finished, counted and credited in the new phase."""
        self._restart_games = True

    def games_in_flight(self) -> bytes:
        """Everything the next ``sample`` call continues from, pickled: the games as they are
        (positions, per-game memory, generators), who plays each and how far each episode got.
        A checkpoint keeps it, so a resumed run goes on with the same games (``restore_games``)."""
        rollout = self.rollout
        state = {
            "needs_seeded_reset": self._needs_seeded_reset,
            "restart_games": self._restart_games,
            "episode": (self._episode_prefix, self._episode_count),
        }
        if rollout is not None:
            state["games"] = self.games
            state["rollout"] = {k: getattr(rollout, k) for k in ("module_ids", "modules", "episode_ids", "env_t", "returns", "observations")}
            state["chunks"] = {k: getattr(self, k) for k in ("_first_infos", "_earlier_chunks") if hasattr(self, k)}
        return pickle.dumps(state)

    def restore_games(self, data: bytes) -> None:
        """Continue the games in flight of ``games_in_flight`` (of the runner with this worker index)."""
        state = pickle.loads(data)
        self._needs_seeded_reset = state["needs_seeded_reset"]
        self._restart_games = state.get("restart_games", False)
        self._episode_prefix, self._episode_count = state["episode"]
        if "games" in state and self.rollout is not None:
            self.games = self.rollout.games = state["games"]
            for key, value in state["rollout"].items():
                setattr(self.rollout, key, value)
            self.rollout.started[:] = time.perf_counter()  # wall clock: the episodes' durations restart
            self._finished, self._outcomes = [], Counter()
            for key, value in state["chunks"].items():
                setattr(self, key, value)

    # ------------------------------------------------------------------ sample
    def sample(
        self,
        *,
        num_timesteps: int | None = None,
        num_episodes: int | None = None,
        explore: bool | None = None,
        random_actions: bool = False,
        force_reset: bool = False,
    ) -> list[MultiAgentEpisode]:
        if self.games is None:
            raise ValueError(f"{self} has no env: it is a local runner beside remote ones")
        if num_timesteps is not None and num_episodes is not None:
            raise ValueError("give either num_timesteps or num_episodes, not both")
        explore = self.config.explore if explore is None else explore
        self.metrics.log_value(key=WEIGHTS_SEQ_NO, value=compat.weights_seq_no(self), window=1)
        with self.metrics.log_time(SAMPLE_TIMER):
            if num_episodes is not None:
                self._reset_all()
                episodes, _, _ = self._play(None, num_episodes, explore, random_actions)
                self._needs_seeded_reset = True
            else:
                if force_reset or self._needs_seeded_reset or self._restart_games:
                    self._reset_all()
                else:  # the fast path may have left some agents' observations out
                    self.rollout.observations = self.games.observations()
                if num_timesteps is None:
                    num_timesteps = self.config.get_rollout_fragment_length(self.worker_index) * self.num_envs
                episodes, rows, t = self._play(math.ceil(num_timesteps / self.num_envs), None, explore, random_actions)
                episodes += self._ongoing_chunks(rows, t)
        make_callback(
            "on_sample_end",
            callbacks_objects=compat.env_runner_callbacks(self),
            callbacks_functions=self.config.callbacks_on_sample_end,
            kwargs=dict(env_runner=self, metrics_logger=self.metrics, samples=episodes),
        )
        return episodes

    def sample_training_data(self, num_timesteps: int) -> dict[str, dict[str, np.ndarray]]:
        """Play at least ``num_timesteps`` env steps, exploring; PPO's training data of every
        trained module straight from the arrays (``league.rollout.train_batch``), no episodes.

        Module id -> columns ``obs``, ``actions``, ``action_logp``, ``action_dist_inputs``,
        ``advantages`` (not yet standardised: that is done over all runners' data) and
        ``value_targets``. Games still running at the end are continued by the next call.
        """
        if self.games is None:
            raise ValueError(f"{self} has no env: it is a local runner beside remote ones")
        self.metrics.log_value(key=WEIGHTS_SEQ_NO, value=compat.weights_seq_no(self), window=1)
        with self.metrics.log_time(SAMPLE_TIMER):
            if self._needs_seeded_reset or self._restart_games:
                self._reset_all()
            _, rows, t = self._play(math.ceil(num_timesteps / self.num_envs), None, True, False, episodes=False)
            self.rollout.env_t += t - rows.chunk_start  # the unfinished episodes go on in the next call
            return self._training_data(rows, t)

    # ------------------------------------------------------------------ games
    def _reset_all(self) -> None:
        n = self.num_envs
        self._first_infos: list[dict] = [RESET_INFOS] * n  # infos of each chunk's first observation
        self._earlier_chunks: dict[str, list[MultiAgentEpisode]] = defaultdict(list)
        self._finished: list[tuple] = []  # (length, agent returns, module returns, seconds) per episode
        self._outcomes: Counter[tuple[tuple[str, ...], str]] = Counter()  # finished games by (modules, outcome)
        self.rollout.reset(seed=compat.env_runner_seed(self) if self._needs_seeded_reset else None)
        self._needs_seeded_reset = self._restart_games = False

    def _play(
        self, num_steps: int | None, num_episodes: int | None, explore: bool, random_actions: bool, episodes: bool = True
    ) -> tuple[list[MultiAgentEpisode], Rows, int]:
        """Step all games ``num_steps`` times, or until ``num_episodes`` have ended.

        Returns the episodes that ended (as ``MultiAgentEpisode``s if ``episodes``, else
        none: their metrics and outcomes are logged all the same), the rows and the steps played.
        """
        done_episodes: list[MultiAgentEpisode] = []

        def game_ended(rows: Rows, game: int, start: int, t: int, outcome: int) -> None:
            if episodes:
                done_episodes.append(self._chunk(rows, game, start, t, ended=True))
            else:
                self._game_ended(game, int(self.rollout.env_t[game]) + t - start, outcome)
            self._first_infos[game] = RESET_INFOS

        rows, t, num_done, module_steps = self.rollout.play(
            num_steps,
            num_episodes,
            act=lambda rows, t: self._act(rows, t, explore, random_actions, on_core=not episodes),
            on_game_end=game_ended,
            observed=(lambda: AGENTS) if episodes else self._agents_that_observe,
        )
        self._count_steps(self.num_envs * t, num_done, module_steps)
        self._log_finished_episodes()
        for (modules, outcome), count in self._outcomes.items():
            log_outcome(self.metrics, list(modules), outcome, count)
        self._outcomes.clear()
        return done_episodes, rows, t

    def _agents_that_observe(self) -> tuple[str, ...]:
        """Agents played by a learned module in some game: the fast path computes no
        observation for the others (scripted players act on the games' state)."""
        scripted = np.array([isinstance(self.module[m], ScriptedModule) for m in self.rollout.module_ids])
        return tuple(agent for i, agent in enumerate(AGENTS) if not scripted[self.rollout.modules[:, i]].all())

    def _ongoing_chunks(self, rows: Rows, t: int) -> list[MultiAgentEpisode]:
        """The episodes still running after row ``t``, as chunks that the next call continues."""
        ongoing = []
        for game in np.flatnonzero(rows.chunk_start < t):
            start = rows.chunk_start[game]
            chunk = self._chunk(rows, game, start, t, ended=False)
            self._earlier_chunks[chunk.id_].append(chunk)
            self.rollout.env_t[game] += t - start
            self._first_infos[game] = {agent: infos[0] for agent, infos in rows.infos(game, t - 1, t).items()}
            ongoing.append(chunk)
        return ongoing

    def _act(self, rows: Rows, t: int, explore: bool, random_actions: bool, on_core: bool) -> dict[str, np.ndarray]:
        """Every agent's action in every game: one forward pass per module.

        With ``on_core``, scripted players act on the games' exact state, as in evaluation
        (``league.evaluation.engine``), rather than on the float32 global state their module reads.
        """
        if random_actions:
            actions = {}
            for agent, space in self._spaces[1].items():
                actions[agent] = np.random.uniform(space.low, space.high, size=(self.num_envs, *space.shape)).astype(np.float32)
            return actions

        def policy_of(module_id: str) -> Policy:
            module = self.module[module_id]
            if on_core and isinstance(module, ScriptedModule):
                return ScriptedOnState(module.name)

            # `LeagueSettings.frozen_players_explore`: a frozen snapshot may play its mean (a scripted
            # player acts alike either way).
            frozen_explores = module.settings.explore_when_frozen if isinstance(module, ActorCriticModule) else True
            explores = explore and (frozen_explores or self._is_trained(module_id))

            def forward(obs: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
                outputs = _forward(module, torch.from_numpy(obs), explores)
                return outputs.pop(Columns.ACTIONS), outputs

            return forward

        with self.metrics.log_time(RLMODULE_INFERENCE_TIMER), torch.no_grad():
            return self.rollout.act_by_module(rows, t, policy_of)

    # ------------------------------------------------------------------ episodes
    def _chunk(self, rows: Rows, game: int, start: int, end: int, ended: bool) -> MultiAgentEpisode:
        """Rows ``start..end`` of ``game`` as a ``MultiAgentEpisode`` chunk of numpy data."""
        episode_id, env_t, length = self.rollout.episode_ids[game], int(self.rollout.env_t[game]), end - start
        modules = {agent: self.rollout.module_ids[i] for agent, i in zip(AGENTS, self.rollout.modules[game])}
        agents = self._learning_agents(modules)
        infos = rows.infos(game, start, end, agents)
        observation_spaces, action_spaces = self._spaces
        agent_episodes = {}
        for agent in agents:
            keys = rows.output_keys.get(modules[agent], ())
            outputs = {key: rows.outputs[(agent, key)][start:end, game].copy() for key in keys}
            outputs[WEIGHTS_SEQ_NO] = np.full(length, compat.weights_seq_no(self))
            agent_episodes[agent] = SingleAgentEpisode(
                id_=f"{episode_id}-{agent}",
                agent_id=agent,
                module_id=modules[agent],
                multi_agent_episode_id=episode_id,
                observations=rows.observations[agent][start : end + 1, game].copy(),
                observation_space=observation_spaces[agent],
                infos=[self._first_infos[game][agent], *infos[agent]],
                actions=rows.actions[agent][start:end, game].copy(),
                action_space=action_spaces[agent],
                rewards=rows.rewards[agent][start:end, game].copy(),
                terminated=ended,
                extra_model_outputs=outputs,
                t_started=env_t,
                len_lookback_buffer=0,
            )
        episode = MultiAgentEpisode(
            id_=episode_id,
            observation_space=observation_spaces,
            action_space=action_spaces,
            agent_module_ids=modules,
            agent_to_module_mapping_fn=self.config.policy_mapping_fn,
            env_t_started=env_t,
            len_lookback_buffer=0,
        )
        compat.lockstep_episode(episode, agent_episodes, env_t, length, terminated=ended)
        if ended:
            self._episode_ended(episode, game, env_t + length)
        return episode

    def _learning_agents(self, modules: dict[str, str]) -> tuple[str, ...]:
        """Agents whose module is trained; all of them when none is (the Learner then drops the chunk)."""
        trained = tuple(agent for agent in AGENTS if self._is_trained(modules[agent]))
        return trained or AGENTS

    def _is_trained(self, module_id: str) -> bool:
        to_train = self.config.policies_to_train
        if to_train is None:
            return True
        return to_train(module_id, None) if callable(to_train) else module_id in to_train

    def _episode_ended(self, episode: MultiAgentEpisode, game: int, length: int) -> None:
        returns = dict(zip(AGENTS, self.rollout.returns[game].tolist()))
        module_returns: dict[str, float] = defaultdict(float)
        for agent, index in zip(AGENTS, self.rollout.modules[game]):
            module_returns[self.rollout.module_ids[index]] += returns[agent]
        duration = time.perf_counter() - self.rollout.started[game]
        self._finished.append((length, returns, dict(module_returns), duration))
        make_callback(
            "on_episode_end",
            callbacks_objects=compat.env_runner_callbacks(self),
            callbacks_functions=self.config.callbacks_on_episode_end,
            kwargs=dict(
                episode=episode,
                prev_episode_chunks=self._earlier_chunks.pop(episode.id_, []),
                env_runner=self,
                metrics_logger=self.metrics,
                env=self.env.unwrapped,
                rl_module=self.module,
                env_index=game,
            ),
        )

    def _game_ended(self, game: int, length: int, outcome: int) -> None:
        """A finished game's metrics and outcome, without an episode object (the fast path)."""
        returns = dict(zip(AGENTS, self.rollout.returns[game].tolist()))
        modules = [self.rollout.module_ids[index] for index in self.rollout.modules[game]]
        module_returns: dict[str, float] = defaultdict(float)
        for agent, module_id in zip(AGENTS, modules):
            module_returns[module_id] += returns[agent]
        self._finished.append((length, returns, dict(module_returns), time.perf_counter() - self.rollout.started[game]))
        self._outcomes[(tuple(modules), Outcome(outcome).label)] += 1  # logged per key after the play: one call, not one a game

    def _training_data(self, rows: Rows, t: int) -> dict[str, dict[str, np.ndarray]]:
        """Every trained module's PPO columns from rows ``0..t`` (see ``sample_training_data``)."""
        ended = (rows.outcome[:t] != int(Outcome.RUNNING)).astype(np.float64)
        data: dict[str, dict[str, list[np.ndarray]]] = {}
        for index, module_id in enumerate(self.rollout.module_ids):
            if not self._is_trained(module_id):
                continue
            module = self.module[module_id]
            settings = module.settings
            method, gamma, lambda_ = settings.reward_method, settings.gamma, settings.lambda_
            for i, agent in enumerate(AGENTS):
                played = rows.modules[:t, :, i] == index  # (t, G)
                if not played.any():
                    continue
                # The observation after the last row is bootstrapped by whoever played the last step.
                observed = np.concatenate((played, played[-1:]))
                obs = rows.observations[agent][: t + 1]
                values = np.zeros(observed.shape)
                with torch.no_grad():
                    values[observed] = module.compute_values({Columns.OBS: torch.from_numpy(obs[observed])}).numpy()
                if agent == "attacker" and method:
                    rewards = rows.attacker_rewards[:t, :, method - 1]  # this module's reward method
                    win_reward = settings.attacker_win_reward
                    if win_reward:  # `PPOSettings.attacker_win_reward`: +R on the step A won a game, -R on one it lost
                        rewards = rewards + win_reward * np.where(attacker_won_games(rows.outcome[:t]), 1.0, -1.0) * ended
                elif settings.team_reward == "shared":  # `PPOSettings.team_reward`
                    rewards = rows.rewards["targeter"][:t] + rows.rewards["defender"][:t]
                else:
                    rewards = rows.rewards[agent][:t]
                shaping = settings.shaping_of(agent)  # `PPOSettings.targeter_shaping`, `defender_shaping`
                if agent in SHAPED_DISTANCE and shaping:
                    distance = SHAPED_DISTANCE[agent](self.games.core.config, obs[:, :, -GLOBAL_STATE_SIZE:])
                    rewards = rewards + potential_shaping(-shaping * distance, ended, gamma)
                advantages, targets = gae(rewards, values[:t], values[t], ended, gamma, lambda_)
                columns = {
                    Columns.OBS: obs[:t][played],
                    Columns.ACTIONS: rows.actions[agent][:t][played],
                    Columns.ACTION_LOGP: rows.outputs[(agent, Columns.ACTION_LOGP)][:t][played],
                    Columns.ACTION_DIST_INPUTS: rows.outputs[(agent, Columns.ACTION_DIST_INPUTS)][:t][played],
                    Postprocessing.ADVANTAGES: advantages[played].astype(np.float32),
                    Postprocessing.VALUE_TARGETS: targets[played].astype(np.float32),
                }
                for key, value in columns.items():
                    data.setdefault(module_id, {}).setdefault(key, []).append(value)
        return {module_id: {k: np.concatenate(v) for k, v in columns.items()} for module_id, columns in data.items()}

    def _log_finished_episodes(self) -> None:
        """The standard runner's episode metrics, for the episodes a window can still hold."""
        window = max(1, math.ceil(self.config.metrics_num_episodes_for_smoothing / (self.config.num_env_runners or 1)))
        for length, returns, module_returns, duration in self._finished[-window:]:
            total = sum(returns.values())
            means = {
                EPISODE_LEN_MEAN: length,
                EPISODE_RETURN_MEAN: total,
                EPISODE_DURATION_SEC_MEAN: duration,
                **{(EPISODE_AGENT_RETURN_MEAN, agent): value for agent, value in returns.items()},
                **{(EPISODE_AGENT_STEPS, agent): length for agent in AGENTS},
                **{(EPISODE_MODULE_RETURN_MEAN, module): value for module, value in module_returns.items()},
            }
            for key, value in means.items():  # leaf by leaf: `log_dict` maps `tree` over the dict each call
                self.metrics.log_value(key, value, window=window)
            for reduce, (length_key, return_key) in (
                ("min", (EPISODE_LEN_MIN, EPISODE_RETURN_MIN)),
                ("max", (EPISODE_LEN_MAX, EPISODE_RETURN_MAX)),
            ):
                self.metrics.log_value(length_key, length, reduce=reduce, window=window)
                self.metrics.log_value(return_key, total, reduce=reduce, window=window)
        self._finished.clear()

    def _count_steps(self, env_steps: int, episodes: int, module_steps: np.ndarray) -> None:
        if env_steps:
            compat.count_sampled_env_steps(self, env_steps)
        self.metrics.log_value(NUM_ENV_STEPS_SAMPLED, env_steps, reduce="sum")
        self.metrics.log_value(NUM_ENV_STEPS_SAMPLED_LIFETIME, env_steps, reduce="lifetime_sum", with_throughput=True)
        self.metrics.log_value(NUM_EPISODES, episodes, reduce="sum")
        self.metrics.log_value(NUM_EPISODES_LIFETIME, episodes, reduce="lifetime_sum")
        for agent in AGENTS:
            self.metrics.log_value((NUM_AGENT_STEPS_SAMPLED, agent), env_steps, reduce="sum")
            self.metrics.log_value((NUM_AGENT_STEPS_SAMPLED_LIFETIME, agent), env_steps, reduce="lifetime_sum")
        for index, steps in enumerate(module_steps.tolist()):
            if steps:
                module_id = self.rollout.module_ids[index]
                self.metrics.log_value((NUM_MODULE_STEPS_SAMPLED, module_id), steps, reduce="sum")
                self.metrics.log_value((NUM_MODULE_STEPS_SAMPLED_LIFETIME, module_id), steps, reduce="lifetime_sum")


def seed_iteration(env_runner: Any, seed: int, iteration: int) -> None:
    """Seed torch's, NumPy's and Python's global generators in ``env_runner``'s process for one
    iteration, from (``seed``, ``iteration``, its worker index); any env runner."""
    words = stream(seed, Purpose.EXPLORATION, iteration, env_runner.worker_index).generate_state(3)
    torch.manual_seed(int(words[0]))
    np.random.seed(int(words[1]))
    random.seed(int(words[2]))


def log_outcome(metrics: Any, modules: list[str], outcome: str, count: int = 1) -> None:
    """Count ``count`` finished games by their (attacker, targeter, defender) modules and outcome."""
    metrics.log_value((OUTCOMES_KEY, SEPARATOR.join(modules), outcome), count, reduce="sum")


def _forward(module: Any, obs: torch.Tensor, explore: bool) -> dict[str, np.ndarray]:
    """Actions, and the distribution's inputs and log-likelihoods, as RLlib's ``GetActions``
    connector computes them: sampled when exploring, the distribution's mode otherwise."""
    if module.training:
        module.eval()  # sampling never trains; saves RLlib's train/eval switch on every call
    batch = {Columns.OBS: obs}
    out = module.forward_exploration(batch) if explore else module.forward_inference(batch)
    if Columns.ACTIONS not in out:
        dist_class = module.get_exploration_action_dist_cls() if explore else module.get_inference_action_dist_cls()
        dist = dist_class.from_logits(out[Columns.ACTION_DIST_INPUTS])
        if not explore:
            dist = dist.to_deterministic()
        out[Columns.ACTIONS] = dist.sample()
        out.setdefault(Columns.ACTION_LOGP, dist.logp(out[Columns.ACTIONS]))
    return {key: value.cpu().numpy() for key, value in out.items() if isinstance(value, torch.Tensor)}

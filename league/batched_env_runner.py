"""The fast sampling path: an RLlib EnvRunner that steps all of its games as arrays.

RLlib's ``MultiAgentEnvRunner`` steps each sub-environment in a Python loop and runs
its connector pipelines on every step. ``BatchedEnvRunner`` keeps everything else of it
(the modules, weight and state sync, checkpoints, metrics, fault tolerance) and replaces
``sample()``: one step of all N games is one call of ``envs.vector_env`` and one forward
pass per module over every (game, agent) it plays. Episodes reach the Learner as
``MultiAgentEpisode`` chunks built from the arrays, with the observations, actions,
rewards, infos and model outputs of the standard path (``tests/test_batched_sampler.py``
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
over the arrays (``league.train_batch``), go straight to the Learner (``LeaguePPO``).
Finished games still log their metrics and match; no episode callback is called.
Scripted players act on the games' exact state (as in evaluation), not on the float32
global state that their RLModule decodes on the other paths.
"""

from __future__ import annotations

import math
import time
import uuid
from collections import defaultdict
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from envs.agents import AGENTS, Outcome
from envs.scripted import ScriptedPlayer
from envs.single import infos_of_steps
from envs.vector_env import TargetDefenseVectorEnv, VectorStep
from league import rllib_compat as compat
from league.modules import ScriptedModule
from league.train_batch import gae
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

RESET_INFOS: dict[str, dict] = {agent: {} for agent in AGENTS}  # what a reset returns as infos
MATCHES_KEY = "league_matches"  # metrics key of the finished games by modules and outcome
SEPARATOR = "|"
EPISODE_ROWS = 64  # first guess of the rows an episode-count sample needs (it grows)


@dataclass(frozen=True)
class EpisodeRef:
    """What this runner hands the agent-to-module mapping: the episode's id (``id_``)."""

    id_: str


class BatchedEnvRunner(MultiAgentEnvRunner):
    """Samples ``num_envs_per_env_runner`` games of ``envs.vector_env`` at once.

    As the standard runner does (``batch_mode="truncate_episodes"``), episodes still
    running at the end of a ``sample()`` call are returned as chunks and continued in
    the next call.
    """

    def __init__(self, config: Any, **kwargs: Any):
        if compat.has_custom_connectors(config):
            raise ValueError("BatchedEnvRunner runs RLlib's default connectors only: use the standard sampler")
        self.games: TargetDefenseVectorEnv | None = None
        super().__init__(config=config, **kwargs)

    def make_env(self) -> None:
        # The standard sub-envs stay for what RLlib reads off them (spaces, callbacks);
        # the games are stepped in `self.games`.
        super().make_env()
        self.games = TargetDefenseVectorEnv(dict(self.config.env_config), self.num_envs)
        env = self.env.envs[0].unwrapped
        self._spaces = (dict(env.observation_spaces), dict(env.action_spaces))
        # As the standard runner: a new env, or a sample by episode count, starts every game
        # anew from the seed; `force_reset` starts them anew where their generators are.
        self._needs_seeded_reset = True

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
                if force_reset or self._needs_seeded_reset:
                    self._reset_all()
                else:  # the fast path may have left some agents' observations out
                    self._observations = self.games.observations()
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
        trained module straight from the arrays (``league.train_batch``), no episodes.

        Module id -> columns ``obs``, ``actions``, ``action_logp``, ``action_dist_inputs``,
        ``advantages`` (not yet standardised: that is done over all runners' data) and
        ``value_targets``. Games still running at the end are continued by the next call.
        """
        if self.games is None:
            raise ValueError(f"{self} has no env: it is a local runner beside remote ones")
        self.metrics.log_value(key=WEIGHTS_SEQ_NO, value=compat.weights_seq_no(self), window=1)
        with self.metrics.log_time(SAMPLE_TIMER):
            if self._needs_seeded_reset:
                self._reset_all()
            _, rows, t = self._play(math.ceil(num_timesteps / self.num_envs), None, True, False, episodes=False)
            self._env_t += t - rows.chunk_start  # the unfinished episodes go on in the next call
            return self._training_data(rows, t)

    # ------------------------------------------------------------------ games
    def _reset_all(self) -> None:
        n = self.num_envs
        self._observations = self.games.reset(seed=compat.env_runner_seed(self) if self._needs_seeded_reset else None)
        self._needs_seeded_reset = False
        self._episode_ids = [""] * n
        self._module_ids: list[str] = []  # modules of the games, indexed by `self._modules`
        self._modules = np.zeros((n, len(AGENTS)), dtype=np.int64)
        self._env_t = np.zeros(n, dtype=np.int64)  # steps of each episode before its current chunk
        self._returns = np.zeros((n, len(AGENTS)))
        self._started = np.zeros(n)
        self._first_infos: list[dict] = [RESET_INFOS] * n  # infos of each chunk's first observation
        self._earlier_chunks: dict[str, list[MultiAgentEpisode]] = defaultdict(list)
        self._finished: list[tuple] = []  # (length, agent returns, module returns, seconds) per episode
        for game in range(n):
            self._start_episode(game)

    def _start_episode(self, game: int) -> None:
        """A fresh episode id for ``game``, and its agents' modules from the mapping."""
        # The league's mapping (`MatchPlan`) reads only the episode's id: no episode object
        # is built per game (RLlib's ids are uuid4 hex strings too).
        episode = EpisodeRef(uuid.uuid4().hex)
        self._episode_ids[game] = episode.id_
        for i, agent in enumerate(AGENTS):
            module_id = self.config.policy_mapping_fn(agent, episode)
            if module_id not in self._module_ids:
                self._module_ids.append(module_id)
            self._modules[game, i] = self._module_ids.index(module_id)
        self._env_t[game] = 0
        self._returns[game] = 0.0
        self._started[game] = time.perf_counter()
        self._first_infos[game] = RESET_INFOS

    def _play(
        self, num_steps: int | None, num_episodes: int | None, explore: bool, random_actions: bool, episodes: bool = True
    ) -> tuple[list[MultiAgentEpisode], "_Rows", int]:
        """Step all games ``num_steps`` times, or until ``num_episodes`` have ended.

        Returns the episodes that ended (as ``MultiAgentEpisode``s if ``episodes``, else
        none: their metrics and match are logged all the same), the rows and the steps played.
        """
        n = self.num_envs
        rows = _Rows(self._observations, num_steps if num_steps is not None else EPISODE_ROWS)
        done_episodes: list[MultiAgentEpisode] = []
        num_done = 0
        module_steps = np.zeros(len(self._module_ids), dtype=np.int64)
        t = 0
        while (t < num_steps) if num_steps is not None else (num_done < num_episodes):
            if t == rows.capacity:
                rows.grow()
            actions = self._act(rows, t, explore, random_actions, on_core=not episodes)
            observed = AGENTS if episodes else self._agents_that_observe()
            result = self.games.step(actions, observed)
            rows.store(t, actions, result, self._modules)
            self._returns += np.stack([result.rewards[agent] for agent in AGENTS], axis=1)
            module_steps = _add_counts(module_steps, self._modules)
            t += 1
            ended = np.flatnonzero(result.done)
            if len(ended):
                num_done += len(ended)
                for game in ended:
                    start = rows.chunk_start[game]
                    if episodes:
                        done_episodes.append(self._chunk(rows, game, start, t, ended=True))
                    else:
                        self._game_ended(game, int(self._env_t[game]) + t - start, int(result.outcome[game]))
                for game in ended:
                    self._start_episode(game)
                observed = AGENTS if episodes else self._agents_that_observe()
                rows.restart(t, ended, self.games.reset_games(ended, observed))
                rows.chunk_start[ended] = t
        self._observations = {agent: rows.observations[agent][t] for agent in AGENTS}
        self._count_steps(n * t, num_done, module_steps)
        self._log_finished_episodes()
        return done_episodes, rows, t

    def _agents_that_observe(self) -> tuple[str, ...]:
        """Agents played by a learned module in some game: the fast path computes no
        observation for the others (scripted players act on the games' state)."""
        scripted = np.array([isinstance(self.module[m], ScriptedModule) for m in self._module_ids])
        return tuple(agent for i, agent in enumerate(AGENTS) if not scripted[self._modules[:, i]].all())

    def _ongoing_chunks(self, rows: "_Rows", t: int) -> list[MultiAgentEpisode]:
        """The episodes still running after row ``t``, as chunks that the next call continues."""
        ongoing = []
        for game in np.flatnonzero(rows.chunk_start < t):
            start = rows.chunk_start[game]
            chunk = self._chunk(rows, game, start, t, ended=False)
            self._earlier_chunks[chunk.id_].append(chunk)
            self._env_t[game] += t - start
            self._first_infos[game] = {agent: infos[0] for agent, infos in rows.infos(game, t - 1, t).items()}
            ongoing.append(chunk)
        return ongoing

    def _act(self, rows: "_Rows", t: int, explore: bool, random_actions: bool, on_core: bool) -> dict[str, np.ndarray]:
        """Every agent's action in every game: one forward pass per module.

        With ``on_core``, scripted players act on the games' exact state, as in evaluation
        (``envs.match``), rather than on the float32 global state their module reads.
        """
        n = self.num_envs
        actions = {agent: np.zeros((n, 2), dtype=np.float32) for agent in AGENTS}
        if random_actions:
            for agent, space in self._spaces[1].items():
                actions[agent] = np.random.uniform(space.low, space.high, size=(n, *space.shape)).astype(np.float32)
            return actions
        with self.metrics.log_time(RLMODULE_INFERENCE_TIMER), torch.no_grad():
            for index in np.unique(self._modules):
                module_id = self._module_ids[index]
                players = [(agent, np.flatnonzero(self._modules[:, i] == index)) for i, agent in enumerate(AGENTS)]
                players = [(agent, games) for agent, games in players if len(games)]
                module = self.module[module_id]
                if on_core and isinstance(module, ScriptedModule):
                    for agent, games in players:
                        actions[agent][games] = ScriptedPlayer(agent, module.name).act(self.games.core)[games]
                    continue
                obs = np.concatenate([rows.observations[agent][t, games] for agent, games in players])
                outputs = _forward(module, torch.from_numpy(obs), explore)
                start = 0
                for agent, games in players:
                    part = slice(start, start + len(games))
                    actions[agent][games] = outputs[Columns.ACTIONS][part]
                    extra = {key: value[part] for key, value in outputs.items() if key != Columns.ACTIONS}
                    rows.store_outputs(t, agent, games, module_id, extra)
                    start += len(games)
        return actions

    # ------------------------------------------------------------------ episodes
    def _chunk(self, rows: "_Rows", game: int, start: int, end: int, ended: bool) -> MultiAgentEpisode:
        """Rows ``start..end`` of ``game`` as a ``MultiAgentEpisode`` chunk of numpy data."""
        episode_id, env_t, length = self._episode_ids[game], int(self._env_t[game]), end - start
        modules = {agent: self._module_ids[i] for agent, i in zip(AGENTS, self._modules[game])}
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
        returns = dict(zip(AGENTS, self._returns[game].tolist()))
        module_returns: dict[str, float] = defaultdict(float)
        for agent, index in zip(AGENTS, self._modules[game]):
            module_returns[self._module_ids[index]] += returns[agent]
        duration = time.perf_counter() - self._started[game]
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
        """A finished game's metrics and match, without an episode object (the fast path)."""
        returns = dict(zip(AGENTS, self._returns[game].tolist()))
        modules = [self._module_ids[index] for index in self._modules[game]]
        module_returns: dict[str, float] = defaultdict(float)
        for agent, module_id in zip(AGENTS, modules):
            module_returns[module_id] += returns[agent]
        self._finished.append((length, returns, dict(module_returns), time.perf_counter() - self._started[game]))
        log_match(self.metrics, modules, Outcome(outcome).label)

    def _training_data(self, rows: "_Rows", t: int) -> dict[str, dict[str, np.ndarray]]:
        """Every trained module's PPO columns from rows ``0..t`` (see ``sample_training_data``)."""
        config = self.config
        ended = (rows.outcome[:t] != int(Outcome.RUNNING)).astype(np.float64)
        data: dict[str, dict[str, list[np.ndarray]]] = {}
        for index, module_id in enumerate(self._module_ids):
            if not self._is_trained(module_id):
                continue
            module = self.module[module_id]
            method = (module.model_config or {}).get("reward_method")
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
                else:
                    rewards = rows.rewards[agent][:t]
                advantages, targets = gae(rewards, values[:t], values[t], ended, config.gamma, config.lambda_)
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
                module_id = self._module_ids[index]
                self.metrics.log_value((NUM_MODULE_STEPS_SAMPLED, module_id), steps, reduce="sum")
                self.metrics.log_value((NUM_MODULE_STEPS_SAMPLED_LIFETIME, module_id), steps, reduce="lifetime_sum")


def log_match(metrics: Any, modules: list[str], outcome: str) -> None:
    """Count one finished game by its (attacker, targeter, defender) modules and outcome."""
    metrics.log_value((MATCHES_KEY, SEPARATOR.join(modules), outcome), 1, reduce="sum")


def _add_counts(counts: np.ndarray, modules: np.ndarray) -> np.ndarray:
    """``counts`` (per module index) plus one step of every (game, agent) in ``modules``."""
    step = np.bincount(modules.ravel())
    if len(step) > len(counts):
        counts = np.concatenate((counts, np.zeros(len(step) - len(counts), dtype=counts.dtype)))
    counts[: len(step)] += step
    return counts


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


class _Rows:
    """One ``sample()`` call's data as arrays ``[row, game, ...]``.

    Observation row ``t`` is what the games saw before step ``t`` (row 0: where the call
    starts); the other arrays hold step ``t``'s actions, module outputs, rewards and infos.
    """

    def __init__(self, observations: dict[str, np.ndarray], capacity: int):
        self.capacity = capacity
        self.num_games = len(next(iter(observations.values())))
        self.observations = {a: np.zeros((capacity + 1, *o.shape), dtype=o.dtype) for a, o in observations.items()}
        for agent, obs in observations.items():
            self.observations[agent][0] = obs
        self.actions = {a: self._new((2,), np.float32) for a in AGENTS}
        self.rewards = {a: self._new((), np.float64) for a in AGENTS}
        self.outputs: dict[tuple[str, str], np.ndarray] = {}  # (agent, output key) -> rows
        self.output_keys: dict[str, tuple[str, ...]] = {}  # module id -> the outputs it returned
        self.steps, self.time_limit, self.outcome = (self._new((), np.int64) for _ in range(3))
        self.attacker_rewards = self._new((3,), np.float64)
        self.modules = self._new((len(AGENTS),), np.int64)  # index of the module each agent played with
        self.chunk_start = np.zeros(self.num_games, dtype=np.int64)  # row of each game's first observation

    def _new(self, shape: tuple[int, ...], dtype: Any) -> np.ndarray:
        return np.zeros((self.capacity, self.num_games, *shape), dtype=dtype)

    def grow(self) -> None:
        """Double the capacity (sampling by episode count does not know its length ahead)."""

        def doubled(array: np.ndarray) -> np.ndarray:
            return np.concatenate((array, np.zeros((self.capacity, *array.shape[1:]), dtype=array.dtype)))

        self.observations = {a: doubled(x) for a, x in self.observations.items()}
        self.actions = {a: doubled(x) for a, x in self.actions.items()}
        self.rewards = {a: doubled(x) for a, x in self.rewards.items()}
        self.outputs = {k: doubled(x) for k, x in self.outputs.items()}
        self.steps, self.time_limit, self.outcome = doubled(self.steps), doubled(self.time_limit), doubled(self.outcome)
        self.attacker_rewards = doubled(self.attacker_rewards)
        self.modules = doubled(self.modules)
        self.capacity *= 2

    def store(self, t: int, actions: dict[str, np.ndarray], result: VectorStep, modules: np.ndarray) -> None:
        self.modules[t] = modules
        for agent in AGENTS:
            self.actions[agent][t] = actions[agent]
            self.rewards[agent][t] = result.rewards[agent]
        for agent, obs in result.observations.items():  # the agents observed (all but on the fast path)
            self.observations[agent][t + 1] = obs
        self.steps[t], self.time_limit[t], self.outcome[t] = result.steps, result.time_limit, result.outcome
        self.attacker_rewards[t] = result.attacker_rewards

    def store_outputs(self, t: int, agent: str, games: np.ndarray, module_id: str, outputs: dict[str, np.ndarray]) -> None:
        self.output_keys[module_id] = tuple(outputs)
        for key, value in outputs.items():
            if (agent, key) not in self.outputs:
                self.outputs[(agent, key)] = self._new(value.shape[1:], value.dtype)
            self.outputs[(agent, key)][t, games] = value

    def restart(self, t: int, games: np.ndarray, observations: dict[str, np.ndarray]) -> None:
        """Row ``t`` of ``games`` becomes the first observation of their new episodes."""
        for agent, obs in observations.items():
            self.observations[agent][t, games] = obs

    def infos(self, game: int, start: int, end: int, agents: tuple[str, ...] = AGENTS) -> dict[str, list[dict]]:
        """Info dicts of ``agents`` after steps ``start..end - 1`` of ``game``."""
        return infos_of_steps(
            self.steps[start:end, game].tolist(),
            self.time_limit[start:end, game].tolist(),
            self.outcome[start:end, game].tolist(),
            self.attacker_rewards[start:end, game].tolist(),
            agents,
        )

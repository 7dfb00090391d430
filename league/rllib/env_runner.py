"""The league's env runners: RLlib ``EnvRunner``s that step all of their games as arrays.

RLlib's ``MultiAgentEnvRunner`` steps each sub-environment in a Python loop and runs
its connector pipelines on every step. ``BatchedEnvRunner`` keeps everything else of it
(the modules, weight and state sync, checkpoints, metrics, fault tolerance) and replaces
its sampling: the games are played by ``league.rollout.games`` (one step of all N games is one
call of ``envs.vector_env`` and one forward pass per module over every (game, agent) it
plays). What the rows become depends on the sampler:

* ``sample_training_data`` is the fast path (``resources.sampler: fast``): no episode objects
  at all; PPO's columns, with advantages and value targets by GAE over the arrays of what each
  learner is paid (``league.rollout.train_batch``, ``league.rollout.training_reward``), go
  straight to the Learner (``LeaguePPO``). Finished games log their metrics and outcome
  (``runner_metrics``); no episode callback is called. Scripted players act on the games'
  exact state (as in evaluation), not on the float32 global state that their RLModule decodes
  on the other paths.
* ``sample`` is RLlib's (``resources.sampler: batched``): the rows become ``MultiAgentEpisode``
  chunks (``episode_chunks``) that RLlib's learner connectors turn into the batch.

Differences from RLlib's runner, all for speed (and ``episode_chunks``' own):

* Of the per-episode metrics (windows of the last 100 episodes) only the episodes
  that can still be in a window are logged at the end of each play.
* The env-to-module and module-to-env connector pipelines are not run. The league uses
  RLlib's defaults, which only batch, sample from the action distribution and unbatch;
  a config with connectors of its own is refused.
* The agent-to-module mapping is asked with an ``EpisodeRef`` (the episode's id, all
  that the league's ``MatchPlan`` reads), once per agent when a game starts.

``SeededEnvRunner`` is RLlib's own runner (``resources.sampler: standard``) with the run's seeds.
"""

from __future__ import annotations

import functools
import math
import pickle
import random
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from envs.agents import AGENTS
from envs.vector_env import TargetDefenseVectorEnv
from league.core.seeding import Purpose, stream, stream_seed
from league.rllib import compat
from league.rllib.episode_chunks import EpisodeChunks
from league.rllib.modules import ActorCriticModule, ScriptedModule
from league.rllib.runner_metrics import FinishedGames, log_sampled_steps, module_step_counts
from league.rollout.games import Policy, Rollout, Rows, ScriptedOnState
from league.rollout.train_batch import slot_batch
from ray.rllib.callbacks.utils import make_callback
from ray.rllib.core.columns import Columns
from ray.rllib.env.multi_agent_env_runner import MultiAgentEnvRunner
from ray.rllib.env.multi_agent_episode import MultiAgentEpisode
from ray.rllib.evaluation.postprocessing import Postprocessing
from ray.rllib.utils.metrics import RLMODULE_INFERENCE_TIMER, SAMPLE_TIMER, WEIGHTS_SEQ_NO


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
    """Samples ``num_envs_per_env_runner`` games of ``envs.vector_env`` at once: PPO's training
    data (``sample_training_data``, the fast path) or RLlib episodes (``sample``)."""

    def __init__(self, config: Any, **kwargs: Any):
        if compat.has_custom_connectors(config):
            raise ValueError("BatchedEnvRunner runs RLlib's default connectors only: use the standard sampler")
        self.games: TargetDefenseVectorEnv | None = None
        self.rollout: Rollout | None = None
        self.chunks = EpisodeChunks(self)
        self.finished = FinishedGames()
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
        self.agent_spaces = (dict(env.observation_spaces), dict(env.action_spaces))
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
            state["chunks"] = self.chunks.state()
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
            self.finished = FinishedGames()
            self.chunks.restore(state["chunks"])

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
        """RLlib's sampling: the finished episodes and the running ones' chunks (``episode_chunks``)."""
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
                episodes += self.chunks.ongoing(rows, t)
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

    def _training_data(self, rows: Rows, t: int) -> dict[str, dict[str, np.ndarray]]:
        """Every trained module's PPO columns from rows ``0..t`` (see ``sample_training_data``)."""
        data: dict[str, dict[str, list[np.ndarray]]] = {}
        for index, module_id in enumerate(self.rollout.module_ids):
            if not self.is_trained(module_id):
                continue
            module = self.module[module_id]
            for agent in AGENTS:
                # `module.settings` is the `TrainingPay` of how its learner is paid.
                values_of = functools.partial(_values, module)
                batch = slot_batch(rows, t, index, agent, module.settings, values_of, self.games.core.config)
                if batch is None:
                    continue
                played = batch.played
                columns = {
                    Columns.OBS: rows.observations[agent][:t][played],
                    Columns.ACTIONS: rows.actions[agent][:t][played],
                    Columns.ACTION_LOGP: rows.outputs[(agent, Columns.ACTION_LOGP)][:t][played],
                    Columns.ACTION_DIST_INPUTS: rows.outputs[(agent, Columns.ACTION_DIST_INPUTS)][:t][played],
                    Postprocessing.ADVANTAGES: batch.advantages,
                    Postprocessing.VALUE_TARGETS: batch.value_targets,
                }
                for key, value in columns.items():
                    data.setdefault(module_id, {}).setdefault(key, []).append(value)
        return {module_id: {k: np.concatenate(v) for k, v in columns.items()} for module_id, columns in data.items()}

    # ------------------------------------------------------------------ games
    def _reset_all(self) -> None:
        self.chunks.reset(self.num_envs)
        self.finished = FinishedGames()
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
                done_episodes.append(self.chunks.finished(rows, game, start, t))
            else:
                self.finished.add(self.rollout, game, int(self.rollout.env_t[game]) + t - start, outcome)
                self.chunks.restarted(game)

        rows, t, num_done, module_steps = self.rollout.play(
            num_steps,
            num_episodes,
            act=lambda rows, t: self._act(rows, t, explore, random_actions, on_core=not episodes),
            on_game_end=game_ended,
            observed=(lambda: AGENTS) if episodes else self._agents_that_observe,
        )
        env_steps = self.num_envs * t
        if env_steps:
            compat.count_sampled_env_steps(self, env_steps)
        log_sampled_steps(self.metrics, env_steps, num_done, module_step_counts(self.rollout, module_steps))
        self.finished.log(self.metrics, self.config.metrics_num_episodes_for_smoothing, self.config.num_env_runners)
        return done_episodes, rows, t

    def _agents_that_observe(self) -> tuple[str, ...]:
        """Agents played by a learned module in some game: the fast path computes no
        observation for the others (scripted players act on the games' state)."""
        scripted = np.array([isinstance(self.module[m], ScriptedModule) for m in self.rollout.module_ids])
        return tuple(agent for i, agent in enumerate(AGENTS) if not scripted[self.rollout.modules[:, i]].all())

    def _act(self, rows: Rows, t: int, explore: bool, random_actions: bool, on_core: bool) -> dict[str, np.ndarray]:
        """Every agent's action in every game: one forward pass per module.

        With ``on_core``, scripted players act on the games' exact state, as in evaluation
        (``league.evaluation.engine``), rather than on the float32 global state their module reads.
        """
        if random_actions:
            actions = {}
            for agent, space in self.agent_spaces[1].items():
                actions[agent] = np.random.uniform(space.low, space.high, size=(self.num_envs, *space.shape)).astype(np.float32)
            return actions

        def policy_of(module_id: str) -> Policy:
            module = self.module[module_id]
            # `LeagueSettings.frozen_players_explore`: a frozen snapshot may play its mean (a scripted
            # player acts alike either way).
            frozen_explores = module.settings.explore_when_frozen if isinstance(module, ActorCriticModule) else True
            return module_policy(module, explore and (frozen_explores or self.is_trained(module_id)), on_core)

        with self.metrics.log_time(RLMODULE_INFERENCE_TIMER), torch.no_grad():
            return self.rollout.act_by_module(rows, t, policy_of)

    def is_trained(self, module_id: str) -> bool:
        """Whether ``module_id`` is trained now (RLlib's ``policies_to_train``)."""
        to_train = self.config.policies_to_train
        if to_train is None:
            return True
        return to_train(module_id, None) if callable(to_train) else module_id in to_train


def seed_iteration(env_runner: Any, seed: int, iteration: int) -> None:
    """Seed torch's, NumPy's and Python's global generators in ``env_runner``'s process for one
    iteration, from (``seed``, ``iteration``, its worker index); any env runner."""
    words = stream(seed, Purpose.EXPLORATION, iteration, env_runner.worker_index).generate_state(3)
    torch.manual_seed(int(words[0]))
    np.random.seed(int(words[1]))
    random.seed(int(words[2]))


def module_policy(module: Any, explore: bool, on_core: bool) -> Policy:
    """How ``module`` plays in the rollout: its forward pass, sampling if ``explore``; with
    ``on_core``, a scripted module's player on the games' exact state."""
    if on_core and isinstance(module, ScriptedModule):
        return ScriptedOnState(module.name)

    def forward(obs: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        outputs = _forward(module, torch.from_numpy(obs), explore)
        return outputs.pop(Columns.ACTIONS), outputs

    return forward


def _values(module: Any, obs: np.ndarray) -> np.ndarray:
    """The critic's values of ``obs``."""
    with torch.no_grad():
        return module.compute_values({Columns.OBS: torch.from_numpy(obs)}).numpy()


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

"""The oracle samplers' episodes: a rollout's rows as RLlib ``MultiAgentEpisode`` chunks.

``sampler: batched`` (``BatchedEnvRunner.sample``) hands RLlib episodes built from the
arrays, with the observations, actions, rewards, infos and model outputs of RLlib's own runner
(``sampler: standard``; ``tests/rllib/test_batched_sampler.py`` plays both side by side), so
RLlib's learner connectors (GAE, ``callbacks.AttackerRewardByMethod``) pay and train on them.
The fast path builds none (``league.rollout.train_batch``); ``tests/rllib/test_fast_path.py``
checks its batch against RLlib's from these episodes.

Differences from RLlib's runner, for speed:

* Episodes carry only the agents whose module is trained (the learning side); the
  Learner would drop the steps of scripted players and frozen snapshots anyway.
  ``episode.module_for`` still names every agent's module. (An episode in which no
  module is trained, as at a phase switch, carries all three agents.)
* Of the episode callbacks only ``on_episode_end`` is called.

As RLlib's runner does (``batch_mode="truncate_episodes"``), episodes still running at the
end of a ``sample()`` call are returned as chunks and continued in the next call.
"""

from __future__ import annotations

from collections import defaultdict
from typing import Any

import numpy as np

from envs.agents import AGENTS
from league.rllib import compat
from league.rollout.games import Rows
from ray.rllib.callbacks.utils import make_callback
from ray.rllib.env.multi_agent_episode import MultiAgentEpisode
from ray.rllib.env.single_agent_episode import SingleAgentEpisode
from ray.rllib.utils.metrics import WEIGHTS_SEQ_NO

RESET_INFOS: dict[str, dict] = {agent: {} for agent in AGENTS}  # what a reset returns as infos


class EpisodeChunks:
    """The episodes of ``runner``'s games: each chunk's first infos, the earlier chunks of the
    episodes in flight (``on_episode_end`` is handed them), and the chunks built from rows."""

    def __init__(self, runner: Any):
        self.runner = runner  # the `env_runner.BatchedEnvRunner` whose games these are
        self.first_infos: list[dict] = []  # infos of each game's next chunk's first observation
        self.earlier: dict[str, list[MultiAgentEpisode]] = defaultdict(list)  # by episode id

    def reset(self, num_games: int) -> None:
        """Every game starts a new episode."""
        self.first_infos = [RESET_INFOS] * num_games
        self.earlier = defaultdict(list)

    def state(self) -> dict[str, Any]:
        """What ``restore`` continues from (the keys are those checkpoints have held)."""
        return {"_first_infos": self.first_infos, "_earlier_chunks": self.earlier}

    def restore(self, state: dict[str, Any]) -> None:
        self.first_infos = state.get("_first_infos", self.first_infos)
        self.earlier = state.get("_earlier_chunks", self.earlier)

    def finished(self, rows: Rows, game: int, start: int, end: int) -> MultiAgentEpisode:
        """The last chunk of ``game``'s episode (rows ``start..end - 1``); its episode callbacks called."""
        episode = self.chunk(rows, game, start, end, ended=True)
        self.restarted(game)
        return episode

    def restarted(self, game: int) -> None:
        """``game`` ended and starts a new episode (its end built into a chunk or not)."""
        self.first_infos[game] = RESET_INFOS

    def ongoing(self, rows: Rows, t: int) -> list[MultiAgentEpisode]:
        """The episodes still running after row ``t``, as chunks that the next call continues."""
        rollout, chunks = self.runner.rollout, []
        for game in np.flatnonzero(rows.chunk_start < t):
            start = rows.chunk_start[game]
            chunk = self.chunk(rows, game, start, t, ended=False)
            self.earlier[chunk.id_].append(chunk)
            rollout.env_t[game] += t - start
            self.first_infos[game] = {agent: infos[0] for agent, infos in rows.infos(game, t - 1, t).items()}
            chunks.append(chunk)
        return chunks

    def chunk(self, rows: Rows, game: int, start: int, end: int, ended: bool) -> MultiAgentEpisode:
        """Rows ``start..end`` of ``game`` as a ``MultiAgentEpisode`` chunk of numpy data."""
        runner = self.runner
        rollout = runner.rollout
        episode_id, env_t, length = rollout.episode_ids[game], int(rollout.env_t[game]), end - start
        modules = rollout.module_agents(game)
        agents = self.learning_agents(modules)
        infos = rows.infos(game, start, end, agents)
        observation_spaces, action_spaces = runner.agent_spaces
        agent_episodes = {}
        for agent in agents:
            keys = rows.output_keys.get(modules[agent], ())
            outputs = {key: rows.outputs[(agent, key)][start:end, game].copy() for key in keys}
            outputs[WEIGHTS_SEQ_NO] = np.full(length, compat.weights_seq_no(runner))
            agent_episodes[agent] = SingleAgentEpisode(
                id_=f"{episode_id}-{agent}",
                agent_id=agent,
                module_id=modules[agent],
                multi_agent_episode_id=episode_id,
                observations=rows.observations[agent][start : end + 1, game].copy(),
                observation_space=observation_spaces[agent],
                infos=[self.first_infos[game][agent], *infos[agent]],
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
            agent_to_module_mapping_fn=runner.config.policy_mapping_fn,
            env_t_started=env_t,
            len_lookback_buffer=0,
        )
        compat.lockstep_episode(episode, agent_episodes, env_t, length, terminated=ended)
        if ended:
            self.episode_ended(episode, game, env_t + length)
        return episode

    def learning_agents(self, modules: dict[str, str]) -> tuple[str, ...]:
        """Agents whose module is trained; all of them when none is (the Learner then drops the chunk)."""
        trained = tuple(agent for agent in AGENTS if self.runner.is_trained(modules[agent]))
        return trained or AGENTS

    def episode_ended(self, episode: MultiAgentEpisode, game: int, length: int) -> None:
        """The finished episode's metrics, and RLlib's ``on_episode_end`` callbacks."""
        runner = self.runner
        runner.finished.add(runner.rollout, game, length)
        make_callback(
            "on_episode_end",
            callbacks_objects=compat.env_runner_callbacks(runner),
            callbacks_functions=runner.config.callbacks_on_episode_end,
            kwargs=dict(
                episode=episode,
                prev_episode_chunks=self.earlier.pop(episode.id_, []),
                env_runner=runner,
                metrics_logger=runner.metrics,
                env=runner.env.unwrapped,
                rl_module=runner.module,
                env_index=game,
            ),
        )

"""The rollout: N games stepped together, each agent of each game played by a module. No Ray.

``Rollout`` holds

* the games (``envs.vector_env``: one array per quantity, games restarted one by one);
* the slots: which module plays each agent of each game (``modules[game, agent]``, an
  index into ``module_ids``), decided once per episode by ``module_for(agent, episode_id)``;
* each game's episode id, steps before its current chunk, running returns and start time;
* the step loop (``play``): every game steps ``num_steps`` times, or until ``num_episodes``
  have ended; the actions come from one call per module (``act``), a game that ends is
  reported (``on_game_end``) and restarted at once (or, for evaluation's fixed games, left
  as it ended).

What the games produced goes into ``Rows``: arrays ``[row, game, ...]``. A module is played
by a ``ModuleAct`` (observations in, actions and per-row outputs out: a network's forward
pass) or, for scripted players, by ``ScriptedOnState`` (they act on the games' exact state).

Used by the RLlib env runner (``league.rllib.env_runner``, which turns the rows into
episodes or PPO's training batch), by evaluation (``league.evaluation.engine``: frozen players on
the fixed games) and by the plain-PyTorch PPO bench (``bench/plain_ppo.py``);
``tests/rollout/test_games.py`` runs it without Ray.
"""

from __future__ import annotations

import time
import uuid
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from envs.agents import AGENTS
from envs.scripted import ScriptedPlayer
from envs.single import infos_of_steps
from envs.vector_env import TargetDefenseVectorEnv, VectorStep

EPISODE_ROWS = 64  # first guess of the rows a play by episode count needs (they grow)

ModuleAct = Callable[[np.ndarray], tuple[np.ndarray, dict[str, np.ndarray]]]
"""A module's forward pass: observations ``(B, size)`` -> actions ``(B, 2)`` and outputs by name, a row each."""


@dataclass(frozen=True)
class ScriptedOnState:
    """A module whose agents are the scripted players ``name`` of ``envs.scripted``, acting on
    the games' exact state (as in evaluation) rather than on observations."""

    name: str


Policy = ModuleAct | ScriptedOnState
GameEnd = Callable[["Rows", int, int, int, int], None]
"""``on_game_end(rows, game, first_row, end_row, outcome)``: the game's rows of this play are ``first_row..end_row - 1``."""


class Rollout:
    """``action_dtype``: of the actions the games are stepped with. The sampler hands RLlib
    float32 actions; evaluation plays the scripted players' float64 actions unrounded, as
    ``envs.match`` does."""

    def __init__(
        self, games: TargetDefenseVectorEnv, module_for: Callable[[str, str], str], action_dtype: Any = np.float32,
        new_episode_id: Callable[[], str] = lambda: uuid.uuid4().hex,
    ):
        """``new_episode_id()`` names each new episode; ``module_for`` may draw its match from
        the name, so a reproducible run names its episodes reproducibly (the sampler does)."""
        self.games = games
        self.module_for = module_for
        self.new_episode_id = new_episode_id
        self.action_dtype = action_dtype
        n = games.num_games
        self.module_ids: list[str] = []  # modules of the games, indexed by `modules`
        self.modules = np.zeros((n, len(AGENTS)), dtype=np.int64)
        self.episode_ids = [""] * n
        self.env_t = np.zeros(n, dtype=np.int64)  # steps of each episode before its current chunk
        self.returns = np.zeros((n, len(AGENTS)))
        self.started = np.zeros(n)  # perf_counter at each episode's start
        self.observations: dict[str, np.ndarray] = {}  # what the games see now, by agent

    @property
    def num_games(self) -> int:
        return self.games.num_games

    def reset(self, seed: int | None, positions: np.ndarray | None = None) -> None:
        """Start every game anew with new episodes: from ``seed`` (or where the games' generators
        are), or from the fixed start ``positions[i]`` of each game ``i``."""
        self.observations = self.games.reset(seed=seed, positions=positions)
        self.module_ids = []
        self.modules[:] = 0
        self.episode_ids = [""] * self.num_games
        self.env_t[:] = 0
        self.returns[:] = 0.0
        self.started[:] = 0.0
        for game in range(self.num_games):
            self.start_episode(game)

    def start_episode(self, game: int) -> None:
        """A fresh episode id for ``game``, and its agents' modules from ``module_for``."""
        episode_id = self.new_episode_id()
        self.episode_ids[game] = episode_id
        for i, agent in enumerate(AGENTS):
            module_id = self.module_for(agent, episode_id)
            if module_id not in self.module_ids:
                self.module_ids.append(module_id)
            self.modules[game, i] = self.module_ids.index(module_id)
        self.env_t[game] = 0
        self.returns[game] = 0.0
        self.started[game] = time.perf_counter()

    def module_agents(self, game: int) -> dict[str, str]:
        """Module id of each agent of ``game``."""
        return {agent: self.module_ids[i] for agent, i in zip(AGENTS, self.modules[game])}

    def play(
        self,
        num_steps: int | None,
        num_episodes: int | None,
        act: Callable[["Rows", int], dict[str, np.ndarray]],
        on_game_end: GameEnd,
        observed: Callable[[], tuple[str, ...]] = lambda: AGENTS,
        restart: bool = True,
    ) -> tuple["Rows", int, int, np.ndarray]:
        """Step all games ``num_steps`` times or until ``num_episodes`` have ended, whichever
        comes first (``None``: no such limit).

        ``act(rows, t)`` gives every agent's actions ``(N, 2)`` before step ``t`` (see
        ``act_by_module``); ``observed()`` the agents whose observations the games compute.
        With ``restart=False`` a game that ends is not started anew: it stays as it ended
        (the core freezes it) and ends no more. Returns the rows, the steps played, the
        episodes ended and the steps each module played (per index of ``module_ids``, one per
        game and agent).
        """
        rows = Rows(self.observations, num_steps if num_steps is not None else EPISODE_ROWS)
        num_done = 0
        module_steps = np.zeros(len(self.module_ids), dtype=np.int64)
        t = 0
        while (num_steps is None or t < num_steps) and (num_episodes is None or num_done < num_episodes):
            if t == rows.capacity:
                rows.grow()
            actions = act(rows, t)
            result = self.games.step(actions, observed())
            rows.store(t, actions, result, self.modules)
            self.returns += np.stack([result.rewards[agent] for agent in AGENTS], axis=1)
            module_steps = add_counts(module_steps, self.modules)
            t += 1
            ended = np.flatnonzero(result.done)
            if len(ended):
                num_done += len(ended)
                for game in ended:
                    on_game_end(rows, game, rows.chunk_start[game], t, int(result.outcome[game]))
                if restart:
                    for game in ended:
                        self.start_episode(game)
                    rows.restart(t, ended, self.games.reset_games(ended, observed()))
                    rows.chunk_start[ended] = t
        self.observations = {agent: rows.observations[agent][t] for agent in AGENTS}
        return rows, t, num_done, module_steps

    def act_by_module(self, rows: "Rows", t: int, policy_of: Callable[[str], Policy]) -> dict[str, np.ndarray]:
        """Every agent's action in every game before step ``t``: one call per module over all
        the (game, agent) slots it plays; the modules' outputs go into ``rows``."""
        actions = {agent: np.zeros((self.num_games, 2), dtype=self.action_dtype) for agent in AGENTS}
        for index in np.unique(self.modules):
            module_id = self.module_ids[index]
            players = [(agent, np.flatnonzero(self.modules[:, i] == index)) for i, agent in enumerate(AGENTS)]
            players = [(agent, games) for agent, games in players if len(games)]
            policy = policy_of(module_id)
            if isinstance(policy, ScriptedOnState):
                for agent, games in players:
                    actions[agent][games] = ScriptedPlayer(agent, policy.name).act(self.games.core)[games]
                continue
            obs = np.concatenate([rows.observations[agent][t, games] for agent, games in players])
            module_actions, outputs = policy(obs)
            start = 0
            for agent, games in players:
                part = slice(start, start + len(games))
                actions[agent][games] = module_actions[part]
                rows.store_outputs(t, agent, games, module_id, {key: value[part] for key, value in outputs.items()})
                start += len(games)
        return actions


def add_counts(counts: np.ndarray, modules: np.ndarray) -> np.ndarray:
    """``counts`` (per module index) plus one step of every (game, agent) in ``modules``."""
    step = np.bincount(modules.ravel())
    if len(step) > len(counts):
        counts = np.concatenate((counts, np.zeros(len(step) - len(counts), dtype=counts.dtype)))
    counts[: len(step)] += step
    return counts


class Rows:
    """One play's data as arrays ``[row, game, ...]``.

    Observation row ``t`` is what the games saw before step ``t`` (row 0: where the play
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
        """Double the capacity (a play by episode count does not know its length ahead)."""

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
        for agent, obs in result.observations.items():  # the agents observed
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

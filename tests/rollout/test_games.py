"""The rollout core (``league.rollout.games``), without Ray: slots, the step loop, one call per module."""

from __future__ import annotations

import numpy as np

from envs.agents import AGENTS, Outcome
from envs.config import GameConfig
from envs.scripted import PAPER_TEAM, ScriptedPlayer
from envs.vector_env import TargetDefenseVectorEnv
from league.rollout.games import Rollout, ScriptedOnState

GAMES = 6
SCRIPTED = {"attacker": "lead_intercept", **PAPER_TEAM}


def games() -> TargetDefenseVectorEnv:
    return TargetDefenseVectorEnv(GameConfig().model_dump(), GAMES)


def all_scripted(agent: str, episode_id: str) -> str:
    return f"scripted-{agent}"


def scripted_policy(module_id: str) -> ScriptedOnState:
    return ScriptedOnState(SCRIPTED[module_id.removeprefix("scripted-")])


def test_the_loop_plays_the_games_as_stepping_them_by_hand():
    rollout = Rollout(games(), all_scripted)
    rollout.reset(seed=4)
    ended = []
    rows, t, num_done, module_steps = rollout.play(
        300, None, lambda rows, t: rollout.act_by_module(rows, t, scripted_policy),
        on_game_end=lambda rows, game, first, end, outcome: ended.append((game, int(first), end, outcome)),
    )
    by_hand = games()
    observations = by_hand.reset(seed=4)
    outcomes = []
    for step in range(300):
        np.testing.assert_array_equal(rows.observations["attacker"][step], observations["attacker"])
        # the rollout's actions are float32, as RLlib's action space
        actions = {agent: ScriptedPlayer(agent, SCRIPTED[agent]).act(by_hand.core).astype(np.float32) for agent in AGENTS}
        result = by_hand.step(actions)
        outcomes.append(result.outcome.copy())  # the games reuse the array when they restart
        observations = result.observations
        done = np.flatnonzero(result.done)
        if len(done):
            restarted = by_hand.reset_games(done)
            for agent in AGENTS:
                observations[agent][done] = restarted[agent]
    np.testing.assert_array_equal(rows.outcome[:t], np.array(outcomes))
    assert t == 300 and num_done == len(ended) == int(np.sum(rows.outcome[:t] != Outcome.RUNNING)) > GAMES
    # every game's episodes follow each other: each starts on the row where the last ended
    for game in range(GAMES):
        spans = [(first, end) for g, first, end, _ in ended if g == game]
        assert spans[0][0] == 0 and all(a[1] == b[0] for a, b in zip(spans, spans[1:]))
        assert all(rows.outcome[end - 1, game] == outcome for g, _, end, outcome in ended if g == game)
    assert module_steps.tolist() == [300 * GAMES] * 3  # one module per agent, every game every step


def test_one_call_per_module_over_all_the_slots_it_plays():
    calls = []

    def team(obs):  # the shared team module: actions and an output that name the observation row
        calls.append(len(obs))
        return np.stack((obs[:, 0], obs[:, 1]), axis=1), {"first": obs[:, 0].copy()}

    rollout = Rollout(games(), lambda agent, _: "team" if agent != "attacker" else "scripted-attacker")
    rollout.reset(seed=1)
    policies = {"team": team, "scripted-attacker": ScriptedOnState("pure_pursuit")}
    rows, t, _, module_steps = rollout.play(5, None, lambda rows, t: rollout.act_by_module(rows, t, policies.__getitem__),
                                            on_game_end=lambda *args: None)
    assert calls == [2 * GAMES] * 5  # T and D of every game in one forward pass per step
    assert rollout.module_ids == ["scripted-attacker", "team"]
    for agent in ("targeter", "defender"):
        np.testing.assert_array_equal(rows.actions[agent][:t], rows.observations[agent][:t, :, :2])
        np.testing.assert_array_equal(rows.outputs[(agent, "first")][:t], rows.observations[agent][:t, :, 0])
    assert ("attacker", "first") not in rows.outputs and rows.output_keys == {"team": ("first",)}
    assert module_steps.tolist() == [5 * GAMES, 2 * 5 * GAMES]


def test_each_episode_draws_its_modules_once_and_by_episode_count_the_rows_grow():
    def by_episode(agent, episode_id):  # two attacker modules, decided by the episode id alone
        return f"attacker-{int(episode_id, 16) % 2}" if agent == "attacker" else f"scripted-{agent}"

    policies = {"attacker-0": ScriptedOnState("pure_pursuit"), "attacker-1": ScriptedOnState("lead_intercept"),
                "scripted-targeter": ScriptedOnState("avoid_attacker"), "scripted-defender": ScriptedOnState("pure_pursuit")}
    rollout = Rollout(games(), by_episode)
    rollout.reset(seed=2)
    first_ids = list(rollout.episode_ids)
    seen = []

    def game_ended(rows, game, first, end, outcome):
        seen.append((rollout.episode_ids[game], rows.modules[first:end, game, 0].tolist()))

    rows, t, num_done, _ = rollout.play(None, 8 * GAMES, lambda rows, t: rollout.act_by_module(rows, t, policies.__getitem__),
                                        on_game_end=game_ended)
    assert num_done >= 8 * GAMES and rows.capacity >= t > 64  # games last longer than the first guess of rows
    assert len({episode for episode, _ in seen}) == len(seen)  # a new id for every episode
    assert {episode for episode, _ in seen} >= set(first_ids) - set(rollout.episode_ids)
    for episode, modules in seen:  # the module of a whole episode is the one its id maps to
        expected = rollout.module_ids.index(by_episode("attacker", episode))
        assert set(modules) == {expected}


def test_without_restarts_each_game_ends_once_and_stays_as_it_ended():
    rollout = Rollout(games(), all_scripted)
    by_hand = games()
    by_hand.reset(seed=9)
    positions = by_hand.core.positions.copy()
    rollout.reset(seed=None, positions=positions)
    np.testing.assert_array_equal(rollout.games.core.positions, positions)
    ended = []
    rows, t, num_done, _ = rollout.play(
        None, GAMES, lambda rows, t: rollout.act_by_module(rows, t, scripted_policy),
        on_game_end=lambda rows, game, first, end, outcome: ended.append((game, end, outcome)), restart=False,
    )
    assert num_done == GAMES and sorted(game for game, _, _ in ended) == list(range(GAMES))
    assert t == max(end for _, end, _ in ended)  # the play stops when the last game ends
    for game, end, outcome in ended:  # after its end a game's outcome and step count stay
        assert (rows.outcome[end - 1 : t, game] == outcome).all() and (rows.steps[end - 1 : t, game] == end).all()

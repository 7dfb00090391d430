"""Frozen players head to head on the fixed evaluation games, played by the rollout (no RLlib sampling stack).

Learned players are RLModules loaded from their saved directories and run with plain
torch forward passes (the Gaussian's mean, i.e. the deterministic action), one per module
and step over all its games (``league.rollout.games``); scripted players are ``envs.scripted``
players acting on the games' exact state. Every pair plays the same fixed seeded games
(``envs.scenarios.evaluation_scenarios``: the ``dev`` games, or the held-out ``test`` games
that only final tables and studies play), each once, to its end.

A side may be a mixture player (``league.core.mixture``): each game is played by the member its
draw picks for that game's index (``mixture_seed``), all of them in one batch; so the same seed
plays the same members on the same games whatever the slices.

``evaluate_pairs`` runs in this process, or spreads the pairs over ``EvaluationWorker``
Ray actors (on any node of the cluster) in slices of the same fixed games; both give the
same numbers (pairs with a mixture are played in this process).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
import torch

from envs.agents import AGENTS
from envs.config import GameConfig
from envs.core import BatchedGame
from envs.match import Controller, GameResults
from envs.observations import policy_input
from envs.scenarios import evaluation_scenarios
from envs.scripted import ScriptedPlayer
from envs.vector_env import TargetDefenseVectorEnv
from league.core.mixture import Contestant, Mixture
from league.core.payoff import OutcomeCount
from league.core.players import Player
from league.rollout.games import ModuleAct, Policy, Rollout, ScriptedOnState

WORKER_START_S = 60.0  # how long evaluation workers may take to start before the driver plays their games
EVALUATION_CHUNK = 64  # steps per rollout play: bounds the rows kept, whatever the number of games

def deterministic(module: torch.nn.Module) -> ModuleAct:
    """A module's forward pass for the rollout: its deterministic action, no other outputs."""

    @torch.no_grad()
    def act(obs: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        return module.deterministic_action(torch.from_numpy(obs)).numpy(), {}

    return act


class LearnedAgent:
    """One agent driven by a saved RLModule's deterministic action, as a controller of
    ``envs.match.play`` (the report's recorded trajectories)."""

    def __init__(self, module: torch.nn.Module, agent: str):
        self.forward = deterministic(module)
        self.index = AGENTS.index(agent)

    def act(self, game: BatchedGame) -> np.ndarray:
        actions, _ = self.forward(policy_input(game.observations()[self.index], game.global_state()))
        return actions.astype(np.float64)


class MissingModuleError(Exception):
    """A learned player's saved module is not where the league database says it is (deleted or moved).

    Raised wherever a saved module is loaded for play (``saved_module``, ``EvaluationPool``);
    the commands (``league.evaluate``, ``league.replay``, ``league.report``, ``league.export``)
    print it as one line and exit 2.
    """

    def __init__(self, player: str, path: str | Path):
        self.player, self.path = player, Path(path)
        super().__init__(f"the saved module of player {player} is missing: {path} not found (deleted or moved?)")


def load_module(path: str | Path) -> torch.nn.Module:
    """A saved player's RLModule, in eval mode (``league.rllib.bridge.load_module``)."""
    from league.rllib import bridge as rllib_bridge

    return rllib_bridge.load_module(path)


def saved_module(player: Player, run_dir: Path, load=None) -> torch.nn.Module:
    """A learned league member's saved module (``load``: a stand-in for ``load_module``)."""
    if not player.checkpoint:
        raise ValueError(f"player {player.name} has no saved module to evaluate")
    try:
        return (load or load_module)(run_dir / player.checkpoint)
    except FileNotFoundError as err:
        raise MissingModuleError(player.name, err.filename or run_dir / player.checkpoint) from err


def policies_of(player: Player, run_dir: Path, load=None) -> dict[str, tuple[str, Policy]]:
    """Module id and policy of each agent of a league member's side."""
    modules = player.modules()
    if player.kind == "scripted":
        names = {
            "attacker": player.scripted_attacker, "targeter": player.scripted_targeter, "defender": player.scripted_defender
        }
        return {agent: (module_id, ScriptedOnState(names[agent])) for agent, module_id in modules.items()}
    act = deterministic(saved_module(player, run_dir, load))
    return {agent: (module_id, act) for agent, module_id in modules.items()}


Lineup = dict[str, tuple[str, Policy]]
"""Module id and policy of every agent of a game."""


def play_fixed_games(game: GameConfig, positions: np.ndarray, policies: Lineup | list[Lineup]) -> GameResults:
    """One game from each start of ``positions`` ``(N, 3, 3)``, played to its end; ``policies``:
    module id and policy of every agent, for every game or (a list) for each game."""
    lineups = policies if isinstance(policies, list) else [policies] * len(positions)
    module_of = [{agent: module_id for agent, (module_id, _) in lineup.items()} for lineup in lineups]
    policy_of = {module_id: policy for lineup in lineups for module_id, policy in lineup.values()}
    observed = tuple(agent for agent in AGENTS
                     if any(not isinstance(lineup[agent][1], ScriptedOnState) for lineup in lineups))
    games = TargetDefenseVectorEnv({**game.model_dump(), "with_global_state": True}, len(positions))
    numbers = iter(range(len(positions)))  # the episodes are named by their game's place, in start order
    rollout = Rollout(games, lambda agent, episode_id: module_of[int(episode_id)][agent], action_dtype=np.float64,
                      new_episode_id=lambda: str(next(numbers)))
    rollout.reset(seed=None, positions=positions)
    attacker_returns = np.zeros((len(positions), 3))
    while games.core.active.any():
        rows, steps, _, _ = rollout.play(
            EVALUATION_CHUNK, int(games.core.active.sum()),
            act=lambda rows, t: rollout.act_by_module(rows, t, policy_of.__getitem__),
            on_game_end=lambda *ended: None, observed=lambda: observed, restart=False,
        )
        for t in range(steps):  # summed step by step, as the returns are
            attacker_returns += rows.attacker_rewards[t]
    core = games.core
    return GameResults(core.outcome.copy(), core.steps.copy(), rollout.returns.copy(), attacker_returns=attacker_returns)


def agents_of(player: Player, run_dir: Path, load=None) -> dict[str, Controller]:
    """The per-agent controllers of a league member (``attacker`` or ``targeter``/``defender``) for ``envs.match.play``."""
    if player.kind == "scripted":
        if player.side == "attacker":
            return {"attacker": ScriptedPlayer("attacker", player.scripted_attacker)}
        return {
            "targeter": ScriptedPlayer("targeter", player.scripted_targeter),
            "defender": ScriptedPlayer("defender", player.scripted_defender),
        }
    module = saved_module(player, run_dir, load)
    agents = ("attacker",) if player.side == "attacker" else ("targeter", "defender")
    return {agent: LearnedAgent(module, agent) for agent in agents}


def lineups_of(contestant: Contestant, run_dir: Path, games: np.ndarray, load=None) -> tuple[list[Lineup], list[str]]:
    """Module id and policy of each agent of ``contestant``'s side, and the player that plays, for each fixed game
    of ``games`` (indices): a mixture's member drawn for the game (from its seed), else the player itself."""
    if not isinstance(contestant, Mixture):
        return [policies_of(contestant, run_dir, load)] * len(games), [contestant.name] * len(games)
    drawn = contestant.draw(contestant.seed, games)
    loaded = {k: policies_of(contestant.members[k], run_dir, load) for k in np.unique(drawn)}
    return [loaded[k] for k in drawn], [contestant.members[k].name for k in drawn]


@dataclass
class PairEvaluation:
    attacker: Contestant
    team: Contestant
    result: GameResults
    # a mixture side's member in each game, by side ("attacker", "team"); empty for a pair of players
    members: dict[str, list[str]] = field(default_factory=dict)

    @property
    def games(self) -> int:
        return len(self.result.outcome)

    @property
    def attacker_wins(self) -> int:
        return int(self.result.attacker_wins.sum())

    @property
    def has_mixture(self) -> bool:
        return isinstance(self.attacker, Mixture) or isinstance(self.team, Mixture)

    def outcome_rows(self) -> list[OutcomeCount]:
        """The store's rows of a pair of players (a mixture has no row in the league)."""
        if self.has_mixture:
            raise ValueError(f"{self.attacker.name} vs {self.team.name}: a mixture's games are not league results")
        return [OutcomeCount(self.attacker.id, self.team.id, label, n) for label, n in self.result.outcome_counts().items() if n]


def evaluate_pair(
    game: GameConfig, attacker: Contestant, team: Contestant, episodes: int, run_dir: Path, start: int = 0, load=None,
    games: str = "dev",
) -> PairEvaluation:
    """Games ``start .. start + episodes`` of the fixed ``games`` (``dev`` or ``test``), ``attacker`` vs ``team``
    (a mixture draws its member of each game from its seed and the game's index)."""
    indices = np.arange(start, start + episodes)
    (attackers, attacker_members), (teams, team_members) = (
        lineups_of(side, run_dir, indices, load) for side in (attacker, team))
    policies = [{**a, **t} for a, t in zip(attackers, teams)]
    result = play_fixed_games(game, evaluation_scenarios(game.scenario, start + episodes, games)[start:], policies)
    members = {side.side: drawn for side, drawn in ((attacker, attacker_members), (team, team_members))
               if isinstance(side, Mixture)}
    return PairEvaluation(attacker, team, result, members)


Progress = Callable[[int, int], None]  # (pairs done, pairs in all), called after each pair


def evaluate_here(
    game: GameConfig, run_dir: Path, pairs: list[tuple[Contestant, Contestant]], episodes: int, games: str = "dev",
    progress: Progress | None = None,
) -> list[PairEvaluation]:
    """Every pair on the first ``episodes`` fixed ``games``, in this process."""
    results = []
    for a, t in pairs:
        results.append(evaluate_pair(game, a, t, episodes, run_dir, games=games))
        if progress:
            progress(len(results), len(pairs))
    return results


class EvaluationWorker:
    """Ray actor body: plays slices of the fixed evaluation games with the modules it is sent.

    Learned modules arrive through Ray's object store, so a worker on any node needs no
    access to the run directory.
    """

    def __init__(self, game: dict, torch_threads: int):
        self.game = GameConfig(**game)
        torch.set_num_threads(torch_threads)

    def ready(self) -> bool:
        return True

    def play(
        self, attacker: Player, team: Player, start: int, episodes: int,
        attacker_module: torch.nn.Module | None = None, team_module: torch.nn.Module | None = None, games: str = "dev",
    ) -> GameResults:
        sent = {str(Path(p.checkpoint)): m for p, m in ((attacker, attacker_module), (team, team_module)) if m is not None}
        return evaluate_pair(self.game, attacker, team, episodes, Path(), start, lambda path: sent[str(path)], games).result


def merge(results: list[GameResults]) -> GameResults:
    return GameResults(
        np.concatenate([r.outcome for r in results]),
        np.concatenate([r.steps for r in results]),
        np.concatenate([r.returns for r in results]),
        attacker_returns=np.concatenate([r.attacker_returns for r in results]),
    )


class EvaluationPool:
    """``workers`` evaluation actors kept for many evaluations (start-up costs seconds).

    The actors are spread over the cluster's nodes (``resources``: custom Ray resources
    each one needs). The driver loads the learned modules from the run directory and
    sends them. A slice whose actor is lost (its node died) is replayed here, and said;
    a new actor is asked for at once, and joins the pool at the first evaluation after Ray
    placed it (when the cluster has room again: a node joined).
    """

    def __init__(
        self, game: GameConfig, run_dir: Path, workers: int, cpus_per_worker: float = 0.5,
        resources: dict[str, float] | None = None, log: Callable[[str], None] = print, torch_threads: int | None = None,
    ):
        import ray

        self.game, self.run_dir, self.log, self.workers = game, Path(run_dir), log, workers
        self.actor_class = ray.remote(num_cpus=cpus_per_worker, resources=resources or {}, scheduling_strategy="SPREAD")(
            EvaluationWorker
        )
        self.threads = torch_threads or max(1, int(cpus_per_worker))  # as `Resources.threads_for`
        self.sent: dict[tuple[str, float], Any] = {}  # (module path, mtime) -> object ref
        self.actors = [self.new_actor() for _ in range(workers)]
        self.replacements: list[tuple[Any, Any]] = []  # (actor, its `ready` call) for each lost actor, until placed
        # Bounded: workers that cannot be placed (their CPUs held by env runners) would wait forever.
        _, pending = ray.wait([actor.ready.remote() for actor in self.actors], num_returns=workers, timeout=WORKER_START_S)
        if pending:
            free = ray.available_resources().get("CPU", 0.0)
            log(
                f"{len(pending)} of {workers} evaluation workers did not start within {WORKER_START_S:.0f} s (each "
                f"needs {cpus_per_worker} CPU{' and ' + str(resources) if resources else ''}; {free:g} CPUs free): "
                "evaluating in the driver instead"
            )
            self.close()
            self.actors = []

    def new_actor(self) -> Any:
        return self.actor_class.remote(self.game.model_dump(), self.threads)

    def lost(self, actor: Any, err: Exception) -> None:
        """``actor`` died (its node with it): out of the pool, a replacement asked for."""
        self.actors.remove(actor)
        replacement = self.new_actor()
        self.replacements.append((replacement, replacement.ready.remote()))
        self.log(
            f"evaluation worker lost ({type(err).__name__}): its games are replayed in the driver; "
            f"{len(self.actors)} of {self.workers} left, a new one joins when the cluster has room"
        )

    def take_replacements(self) -> None:
        """Replacements that Ray has placed and started join the pool; the others keep waiting."""
        import ray

        if not self.replacements:
            return
        ready, _ = ray.wait([ref for _, ref in self.replacements], num_returns=len(self.replacements), timeout=0)
        for actor, ref in [r for r in self.replacements if r[1] in ready]:
            self.replacements.remove((actor, ref))
            try:
                ray.get(ref)
            except ray.exceptions.RayError:  # it died before it started: ask again
                again = self.new_actor()
                self.replacements.append((again, again.ready.remote()))
                continue
            self.actors.append(actor)
            self.log(f"evaluation worker back: {len(self.actors)} of {self.workers}")

    def module_ref(self, player: Player) -> Any:
        import ray

        if player.kind == "scripted":
            return None
        path = self.run_dir / player.checkpoint
        try:
            key = (str(path), (path / "module_state.pkl").stat().st_mtime)  # a learner saved anew is sent anew
        except FileNotFoundError as err:
            raise MissingModuleError(player.name, err.filename) from err
        if key not in self.sent:
            self.sent[key] = ray.put(saved_module(player, self.run_dir))
        return self.sent[key]

    def evaluate(
        self, pairs: list[tuple[Player, Player]], episodes: int, games: str = "dev", progress: Progress | None = None
    ) -> list[PairEvaluation]:
        import ray

        self.take_replacements()
        if not self.actors:
            return evaluate_here(self.game, self.run_dir, pairs, episodes, games, progress)
        bounds = np.linspace(0, episodes, len(self.actors) + 1).astype(int)
        slices = [(int(lo), int(hi - lo)) for lo, hi in zip(bounds[:-1], bounds[1:]) if hi > lo]
        futures = [
            [
                (actor, start, n, actor.play.remote(a, t, start, n, self.module_ref(a), self.module_ref(t), games))
                for actor, (start, n) in zip(self.actors, slices)
            ]
            for a, t in pairs
        ]
        results = []
        for (a, t), pair_futures in zip(pairs, futures):
            parts = []
            for actor, start, n, future in pair_futures:
                try:
                    parts.append(ray.get(future))
                except ray.exceptions.RayActorError as err:
                    if actor in self.actors:
                        self.lost(actor, err)
                    parts.append(evaluate_pair(self.game, a, t, n, self.run_dir, start, games=games).result)
            results.append(PairEvaluation(a, t, merge(parts)))
            if progress:
                progress(len(results), len(pairs))
        return results

    def close(self) -> None:
        import ray

        for actor in self.actors + [actor for actor, _ in self.replacements]:
            ray.kill(actor)


@dataclass(frozen=True)
class Workers:
    """Evaluation workers started for one ``evaluate_pairs`` call: how many, and each one's CPUs,
    custom Ray resources and torch threads."""

    count: int
    cpus: float = 0.5
    resources: dict[str, float] | None = None
    torch_threads: int | None = None


def evaluate_pairs(
    game: GameConfig,
    run_dir: Path,
    pairs: list[tuple[Contestant, Contestant]],
    episodes: int,
    workers: int | Workers = 0,
    pool: EvaluationPool | None = None,
    games: str = "dev",
    progress: Progress | None = None,
) -> list[PairEvaluation]:
    """Every pair on the first ``episodes`` fixed ``games``: on ``pool``, on ``workers`` new actors (a count,
    or ``Workers``), or here (``progress``: told after each pair). Pairs with a mixture (its members drawn
    from its seed) are played here, after the others, and put back in their places."""
    mixed = [k for k, (a, t) in enumerate(pairs) if isinstance(a, Mixture) or isinstance(t, Mixture)]
    if mixed:
        plain = [pair for k, pair in enumerate(pairs) if k not in mixed]
        done = evaluate_pairs(game, run_dir, plain, episodes, workers, pool, games) if plain else []
        here = evaluate_here(game, run_dir, [pairs[k] for k in mixed], episodes, games)
        by_place = dict(zip(mixed, here)) | dict(zip([k for k in range(len(pairs)) if k not in mixed], done))
        if progress:
            progress(len(pairs), len(pairs))
        return [by_place[k] for k in range(len(pairs))]
    if pool is not None:
        return pool.evaluate(pairs, episodes, games, progress)
    spec = workers if isinstance(workers, Workers) else Workers(workers)
    if spec.count <= 0:
        return evaluate_here(game, run_dir, pairs, episodes, games, progress)
    pool = EvaluationPool(game, run_dir, spec.count, spec.cpus, spec.resources, torch_threads=spec.torch_threads)
    try:
        return pool.evaluate(pairs, episodes, games, progress)
    finally:
        pool.close()

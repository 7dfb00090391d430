"""The batched game: N independent games of 3D cooperative target defense as numpy arrays.

Every adapter (PettingZoo, RLlib) and every evaluation loop steps this one core, so the
rules exist once. Arrays are indexed ``[game, agent, ...]`` with agents in the order of
``envs.agents.AGENTS`` (attacker, targeter, defender).

No auto-reset: a finished game stays frozen (its rewards are 0, its ``outcome`` kept)
until the caller resets it with ``reset_games``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envs import rewards
from envs.agents import ATTACKER, ATTACKER_WIN_VALUES, DEFENDER, TARGETER, Outcome
from envs.config import GameConfig
from envs.geometry import angle_between, intercept_time, lead_intercept, norm
from envs.kinematics import Arcs, heading_vectors, limit_turn, turned, wrap_to_pi
from envs.observations import global_state, observe
from envs.scenarios import sample_positions
from envs.sweep import first_contact_on_arcs

NUM_AGENTS = 3
ACTION_SIZE = 2
# Tie order of events within one step: A's capture first (the team must catch A *before*
# T is caught), then T at the terminal, then D's capture of A.
EVENT_ORDER = np.array([Outcome.CAPTURED, Outcome.TERMINAL_REACHED, Outcome.ATTACKER_INTERCEPTED])
# The two bodies of each event, in EVENT_ORDER; body 3 is the terminal, resting at the origin.
TERMINAL_BODY = NUM_AGENTS
EVENT_PAIRS = np.array([[TARGETER, ATTACKER], [TARGETER, TERMINAL_BODY], [ATTACKER, DEFENDER]])
# Gamma = ceil(x) counts x within this relative distance above an integer as that integer:
# 2 |T0| / v_T carries ~1e-16 relative rounding (2 * 8.255 / 0.13 = 127.00000000000001).
TIME_LIMIT_ROUNDING = 1e-9
RUNNING, TIMEOUT = int(Outcome.RUNNING), int(Outcome.TIMEOUT)


@dataclass
class StepResult:
    """What one step of the batch returns (arrays over games)."""

    rewards: np.ndarray  # (N, 3) float
    done: np.ndarray  # (N,) bool: the game ended on this step
    outcome: np.ndarray  # (N,) int: an ``Outcome`` value, RUNNING if still going
    event_fraction: np.ndarray  # (N,) float: when in the step the ending event happened (1 for timeout)
    attacker_rewards: np.ndarray  # (N, 3) float: A's reward under methods 1, 2, 3 (with any terminal reward)


class BatchedGame:
    """N games stepped together. See ``envs.pettingzoo_env`` for the rules in one place."""

    def __init__(self, config: GameConfig, num_games: int):
        self.config = config
        self.num_games = num_games
        self.speeds = np.asarray(config.speeds)
        # The axis length caps the heading change per step at v / L (envs.kinematics).
        self.max_turn = self.speeds / config.axis_length if config.axis_length > 0 else np.full(3, np.inf)
        self.event_radii = np.array([config.attacker_radius, config.terminal_sphere_radius, config.defender_radius])
        self.positions = np.zeros((num_games, NUM_AGENTS, 3))
        self.headings = np.zeros((num_games, NUM_AGENTS, 2))
        self.steps = np.zeros(num_games, dtype=np.int64)
        self.time_limit = np.ones(num_games, dtype=np.int64)
        self.outcome = np.zeros(num_games, dtype=np.int64)
        # Per-game memory of the attacker rewards: T's velocity over the last step
        # (method 2's reference), lambda of the last step and the over-chasing count (method 3).
        self.targeter_velocity = np.zeros((num_games, 3))
        self.collision_distance = np.zeros(num_games)
        self.overchase_count = np.zeros(num_games, dtype=np.int64)
        # A's memory when ``config.attacker_memory``: T's largest turn away from home so far.
        self.targeter_turned_away = np.zeros(num_games)
        # The unit vectors of the headings after the last step, with the headings they belong
        # to: the next step starts from them unless the headings were changed in between.
        self._vectors_of: tuple[np.ndarray, np.ndarray] | None = None

    # ----------------------------------------------------------------- reset
    def reset(self, rng: np.random.Generator | None = None, positions: np.ndarray | None = None) -> None:
        """Start every game: from ``positions`` ``(N, 3, 3)`` if given, else drawn from ``rng``."""
        self.reset_games(np.arange(self.num_games), rng=rng, positions=positions)

    def reset_games(
        self, games: np.ndarray, rng: np.random.Generator | None = None, positions: np.ndarray | None = None
    ) -> None:
        """Start the games at indices ``games`` anew."""
        games = np.asarray(games)
        if positions is None:
            if rng is None:
                raise ValueError("reset needs either a generator `rng` or starting `positions`")
            positions = sample_positions(self.config.scenario, rng, len(games))
        positions = np.asarray(positions, dtype=np.float64)
        if positions.shape != (len(games), NUM_AGENTS, 3):
            raise ValueError(f"starting positions must have shape ({len(games)}, 3, 3), got {positions.shape}")
        self.positions[games] = positions
        self.headings[games] = 0.0  # the paper's initial angles: yaw = pitch = 0
        if self._vectors_of is not None:
            self._vectors_of[0][games] = 0.0
            self._vectors_of[1][games] = (1.0, 0.0, 0.0)  # heading_vectors of (0, 0), exactly
        self.steps[games] = 0
        self.time_limit[games] = time_limit_steps(self.config, norm(positions[:, TARGETER]))
        self.outcome[games] = Outcome.RUNNING
        velocity = self.config.v_targeter * heading_vectors(self.headings[games, TARGETER])
        self.targeter_velocity[games] = velocity
        self.collision_distance[games] = self._collision_distance(positions, velocity)
        self.overchase_count[games] = 0
        self.targeter_turned_away[games] = 0.0

    # ----------------------------------------------------------------- views
    @property
    def active(self) -> np.ndarray:
        running: np.ndarray = self.outcome == RUNNING
        return running

    @property
    def time_left(self) -> np.ndarray:
        """Fraction of the time limit still to play, in ``[0, 1]``."""
        return 1.0 - self.steps / self.time_limit

    def observations(self) -> list[np.ndarray]:
        """``[attacker, targeter, defender]`` observations, each ``(N, size)``."""
        return observe(
            self.config, self.positions, self.headings, self.time_left, targeter_turned_away=self.targeter_turned_away
        )

    def global_state(self) -> np.ndarray:
        return global_state(self.config, self.positions, self.headings, self.time_left)

    def _collision_distance(self, positions: np.ndarray, targeter_velocity: np.ndarray) -> np.ndarray:
        """Method 3's ``lambda``: distance from A to its lead-intercept point on T (``v_A t*``)."""
        speed = self.config.v_attacker
        return speed * intercept_time(positions[:, ATTACKER], speed, positions[:, TARGETER], targeter_velocity)

    # ----------------------------------------------------------------- step
    def commanded_turn(self, actions: np.ndarray) -> np.ndarray:
        """The (yaw, pitch) change ``(N, 3, 2)`` the actions make within the turn limits."""
        actions = np.asarray(actions, dtype=np.float64)
        if actions.shape != (self.num_games, NUM_AGENTS, ACTION_SIZE):
            raise ValueError(
                f"actions must have shape ({self.num_games}, {NUM_AGENTS}, {ACTION_SIZE}), got {actions.shape}"
            )
        if not np.all(np.isfinite(actions)):
            raise ValueError("actions contain NaN or infinity")
        cfg = self.config
        if cfg.action_mode == "relative":
            clipped = np.clip(actions, -1.0, 1.0)
            yaw_change, pitch_change = clipped[..., 0] * cfg.max_yaw_change, clipped[..., 1] * cfg.max_pitch_change
        else:  # absolute: the desired heading, reached as far as the turn limits allow
            yaw_change = wrap_to_pi(actions[..., 0] - self.headings[..., 0])
            pitch_change = actions[..., 1] - self.headings[..., 1]
        return limit_turn(
            self.headings, yaw_change, pitch_change, cfg.max_yaw_change, cfg.max_pitch_change, self.max_turn
        )

    def step(self, actions: np.ndarray) -> StepResult:
        """Advance every running game by one step; finished games stay as they are."""
        cfg = self.config
        change = self.commanded_turn(actions)
        headings = turned(self.headings, change)
        running = self.active
        before = self.positions
        arcs = Arcs.of_turn(before, self.headings, headings, change, self.speeds, self._heading_vectors())
        after = arcs.end

        # Events, swept along the arcs over the whole step, in EVENT_ORDER (envs.sweep).
        contact = self._contact_fractions(arcs)
        first = np.argmin(contact, axis=1)  # argmin keeps the first on ties: EVENT_ORDER
        event_fraction = contact[np.arange(self.num_games), first]
        event = EVENT_ORDER[first]
        steps = self.steps + 1
        timeout = steps >= self.time_limit
        outcome = np.where(np.isfinite(event_fraction), event, np.where(timeout, TIMEOUT, RUNNING))
        outcome = np.where(running, outcome, self.outcome)
        event_fraction = np.where(np.isfinite(event_fraction), event_fraction, 1.0)

        reward, attacker_rewards = self._rewards(before, after, headings)
        if cfg.attacker_memory:
            self._remember_turn_away(before, arcs, running)
        done = running & (outcome != RUNNING)
        if cfg.terminal_reward:
            attacker_won = np.isin(outcome, ATTACKER_WIN_VALUES)
            bonus = np.where(done & attacker_won, cfg.terminal_reward, np.where(done, -cfg.terminal_reward, 0.0))
            reward = reward + bonus[:, None] * np.array([1.0, -1.0, -1.0])
            attacker_rewards = attacker_rewards + bonus[:, None]
        reward = np.where(running[:, None], reward, 0.0)
        attacker_rewards = np.where(running[:, None], attacker_rewards, 0.0)

        keep = ~running
        self.positions = np.where(keep[:, None, None], before, after)
        self.headings = np.where(keep[:, None, None], self.headings, headings)
        vectors = np.where(keep[:, None, None], arcs.tangent, arcs.end_tangent)
        self._vectors_of = (self.headings.copy(), vectors)
        self.steps = np.where(running, steps, self.steps)
        self.outcome = outcome
        return StepResult(reward, done, outcome, event_fraction, attacker_rewards)

    def _remember_turn_away(self, before: np.ndarray, arcs: Arcs, running: np.ndarray) -> None:
        """Keep T's largest turn away from its line home (from where the step started), per game."""
        home = -before[:, TARGETER]
        turned_away = angle_between(arcs.end_tangent[:, TARGETER], home) - angle_between(arcs.tangent[:, TARGETER], home)
        fraction = np.clip(turned_away / min(self.max_turn[TARGETER], np.pi), 0.0, 1.0)
        self.targeter_turned_away = np.where(running, np.maximum(self.targeter_turned_away, fraction), self.targeter_turned_away)

    def _heading_vectors(self) -> np.ndarray:
        """Unit vectors of ``self.headings``: those of the last step if the headings are unchanged."""
        if self._vectors_of is not None and np.array_equal(self._vectors_of[0], self.headings):
            return self._vectors_of[1]
        return heading_vectors(self.headings)

    def _contact_fractions(self, arcs: Arcs) -> np.ndarray:
        """``(N, 3)``: when in the step each event's pair first comes within its radius (``inf``: never)."""
        return first_contact_on_arcs(arcs, EVENT_PAIRS, self.event_radii)

    def _rewards(self, before: np.ndarray, after: np.ndarray, headings: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rewards of the step ``before -> after`` ending at ``headings``; updates the attacker's memory.

        Returns ``(rewards (N, 3 agents), attacker rewards (N, 3 methods))``: all three
        attacker methods are computed every step, so that a league can train attackers
        of different methods on the same games; column 0 of the first uses the
        configured method.
        """
        cfg = self.config
        gamma_steps = self.time_limit.astype(np.float64)
        running = self.active
        d_at = norm(after[:, ATTACKER] - after[:, TARGETER])
        d_da = norm(after[:, DEFENDER] - after[:, ATTACKER])
        velocity = after[:, TARGETER] - before[:, TARGETER]

        method1 = rewards.attacker_method1(
            norm(before[:, ATTACKER] - before[:, TARGETER]), d_at,
            norm(before[:, ATTACKER] - before[:, DEFENDER]), d_da, gamma_steps,
        )
        aim = lead_intercept(before[:, ATTACKER], cfg.v_attacker, before[:, TARGETER], self.targeter_velocity)
        if cfg.method2_direction == "chord":
            direction = after[:, ATTACKER] - before[:, ATTACKER]
        else:  # "heading": where A points at the end of the step
            direction = heading_vectors(headings[:, ATTACKER])
        offset = angle_between(direction, aim - before[:, ATTACKER])
        method2 = rewards.attacker_method2(offset, cfg.sigma_a, gamma_steps)
        collision_distance = self._collision_distance(after, velocity)
        method3, count = rewards.attacker_method3(
            self.collision_distance, collision_distance, self.overchase_count, cfg.overchase_gamma, gamma_steps,
            cfg.method3_variant,
        )
        self.collision_distance = np.where(running, collision_distance, self.collision_distance)
        self.overchase_count = np.where(running, count, self.overchase_count)
        self.targeter_velocity = np.where(running[:, None], velocity, self.targeter_velocity)

        by_method = np.stack((method1, method2, method3), axis=1)
        r_t, r_d = rewards.team_rewards(norm(after[:, TARGETER]), d_at, d_da, cfg.w_t1, cfg.w_t2, gamma_steps)
        return np.stack((by_method[:, cfg.attacker_reward - 1], r_t, r_d), axis=1), by_method


def time_limit_steps(config: GameConfig, start_distance: np.ndarray) -> np.ndarray:
    """``Gamma = ceil(time_limit_factor * |T0 - ter| / v_T)`` steps (at least 1), per game.

    A ratio within ``TIME_LIMIT_ROUNDING`` (relative) above an integer is that integer:
    ``|T0| = 8.255`` gives 127 steps, not 128 from the last bit of a float division.
    """
    ratio = config.time_limit_factor * np.asarray(start_distance, dtype=np.float64) / config.v_targeter
    return np.ceil(ratio * (1.0 - TIME_LIMIT_ROUNDING)).astype(np.int64).clip(min=1)

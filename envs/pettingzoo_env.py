"""PettingZoo ``ParallelEnv`` of one game of 3D cooperative target defense."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from envs.agents import AGENTS
from envs.config import GameConfig
from envs.single import SingleGame, state_space


class TargetDefenseEnv(ParallelEnv):  # type: ignore[misc]  # pettingzoo has no type information: ParallelEnv is Any
    """Attacker A chases targeter T, which flies to the terminal while defender D guards it.

    ## Description
    The three-agent game of ``shared/paper.md`` in 3D, as fixed by ``shared/design.md``.
    All rules live in ``envs.core.BatchedGame``; this class is the API adapter.

    ## Action Space (per agent)
    ``action_mode: relative`` (default), ``Box(-1, 1, (2,))``:

    | index | meaning                              | min | max |
    | ----- | ------------------------------------ | --- | --- |
    | 0     | yaw change / ``max_yaw_change``      | -1  | 1   |
    | 1     | pitch change / ``max_pitch_change``  | -1  | 1   |

    ``action_mode: absolute`` (the paper's), the desired heading, reached as far as the
    turn limits allow this step:

    | index | meaning | min   | max   |
    | ----- | ------- | ----- | ----- |
    | 0     | yaw     | 0     | 2 pi  |
    | 1     | pitch   | -pi/2 | pi/2  |

    Both modes reach the same headings. Values outside the box are clipped; NaN, complex
    values or a wrong shape raise ``ValueError``; ``step()`` before ``reset()`` or after
    the game ended raises ``RuntimeError``.

    ## Observation Space
    ``Box(-inf, inf)``; layouts ``paper`` (15 numbers, 17 for T and D) and ``rich`` (21,
    23 for T and D) are tabled in ``envs.observations``. ``state()`` gives the 22-number
    global state of a centralized critic.

    ## Kinematics
    Constant speed, yaw change at most ``pi/2`` and pitch change at most ``pi/4`` per
    step, turn radius never below ``L``: the true angle between the old and the new
    heading (after the pitch clamp) is at most ``v / L``. Each body flies the circular
    arc between its headings; see ``envs.kinematics``.

    ## Rewards
    A: one of the paper's methods 1, 2, 3 (``attacker_reward``); T and D: Eq. 10, 11 with
    the sign fixed (rewards are negated costs). Optional ``terminal_reward`` (any float
    ``>= 0``, default 0): ``+terminal_reward`` to the winner's agents and ``-terminal_reward``
    to the loser's in the game's last step. See ``envs.rewards``.

    ## Readings of the paper (``GameConfig`` options)
    * ``axis_length``: ``0.1`` (default), ``L`` bounds the true heading change to ``v / L``;
      ``0`` leaves ``L`` out (the explicit yaw and pitch limits alone).
    * ``method2_direction``: ``chord`` (default), Eq. 8's "actual direction" of A is the
      chord of its step; ``heading``, A's heading at the end of the step.
    * ``method3_variant``: ``as_printed`` (default), Eq. 9 as printed; ``corrected``, the
      over-chasing case costs ``(min(2 |dl|, 1) + gamma ** C) * 10 / Gamma``.

    ``Gamma = ceil(2 |T0| / v_T)`` is taken with a 1e-9 relative tolerance, so an exact
    multiple is not pushed one step up by float rounding.

    ## Starting State
    Positions drawn from the scenario set ``scenario`` (``envs.scenarios``) with the
    seeded generator, or given as ``reset(options={"positions": array (3 agents, 3)})``
    to replay a fixed game (finite real numbers, else ``ValueError``); all headings
    yaw = pitch = 0.

    ## Episode End
    All are *terminations* of all three agents, with ``infos[agent]["outcome"]``:

    | outcome                | winner   | condition                                          |
    | ---------------------- | -------- | -------------------------------------------------- |
    | ``captured``           | attacker | A within ``attacker_capture_radius`` of T          |
    | ``timeout``            | attacker | ``Gamma`` steps without T at the terminal          |
    | ``terminal_reached``   | team     | T within ``terminal_radius`` of ``(0, 0, 0)``      |
    | ``attacker_intercepted`` | team   | D within ``defender_capture_radius`` of A          |

    Events are checked over the whole step, along the arcs the bodies fly, to a distance
    tolerance of 1e-9 (``envs.sweep``); the earliest counts, A's capture on a tie. The
    time limit is a termination, not a truncation: it decides the game, and the ``rich``
    observation carries the time left.

    ## Arguments
    Any field of ``envs.config.GameConfig`` as a keyword, or ``config=GameConfig(...)``.
    """

    metadata: dict[str, Any] = {"name": "target_defense_v0", "render_modes": ["rgb_array"], "is_parallelizable": True}

    def __init__(self, config: GameConfig | None = None, render_mode: str | None = None, **overrides: Any):
        """``render_mode="rgb_array"``: ``render()`` returns the game so far as the picture of
        ``python -m envs.render`` (an RGB array); ``None``: nothing is drawn or recorded."""
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode {render_mode!r} is not supported; choose one of {self.metadata['render_modes']} or None")
        self.config = config or GameConfig(**overrides)
        self.game = SingleGame(self.config)
        self.possible_agents = list(AGENTS)
        self.agents: list[str] = []
        self.observation_spaces = self.game.observation_spaces
        self.action_spaces = self.game.action_spaces
        self.state_space = state_space()
        self.render_mode = render_mode
        self._path: list[np.ndarray] = []  # positions (3, 3) after each step, for `render`

    def observation_space(self, agent: str) -> spaces.Box:
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Box:
        return self.action_spaces[agent]

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        positions = (options or {}).get("positions")
        if positions is not None:
            positions = np.asarray(positions)
            if positions.shape != (len(AGENTS), 3):
                raise ValueError(f"options['positions'] must have shape ({len(AGENTS)}, 3), got {positions.shape}")
            if not np.isrealobj(positions) or not np.all(np.isfinite(positions)):
                raise ValueError(f"options['positions'] must be finite real numbers, got {positions.tolist()}")
        observations = self.game.reset(seed, positions)
        self.agents = list(AGENTS)
        if self.render_mode:
            self._path = [self.game.core.positions[0].copy()]
        return observations

    def step(self, actions: dict[str, np.ndarray]) -> tuple[
        dict[str, np.ndarray], dict[str, float], dict[str, bool], dict[str, bool], dict[str, dict[str, Any]]
    ]:
        if not self.agents:
            raise RuntimeError("no game is running: call reset() before step() (and again after a game ends)")
        for agent, action in actions.items():
            if np.iscomplexobj(action):
                raise ValueError(f"action of {agent!r} is complex: {action}; actions are real (yaw, pitch) turns")
        obs, rewards, done, infos = self.game.step(actions)
        if self.render_mode:
            self._path.append(self.game.core.positions[0].copy())
        terminations = {agent: done for agent in self.agents}
        truncations = {agent: False for agent in self.agents}
        if done:
            self.agents = []
        return obs, rewards, terminations, truncations, infos

    def state(self) -> np.ndarray:
        return self.game.state()

    def render(self) -> np.ndarray | None:
        """The game since the last reset as an RGB array ``(height, width, 3)`` (``render_mode="rgb_array"``;
        the drawing of ``envs.render``), or None without a render mode."""
        if not self.render_mode:
            return None
        if not self._path:
            raise RuntimeError("nothing to render: call reset() first")
        from envs.agents import Outcome
        from envs.render import episode_image

        return episode_image(np.stack(self._path), Outcome(int(self.game.core.outcome[0])), self.config, "target defense")

    def close(self) -> None:
        pass


def parallel_env(**kwargs: Any) -> TargetDefenseEnv:
    return TargetDefenseEnv(**kwargs)

"""What each agent sees, and the global state of the centralized critic.

``paper`` (the paper's section 4.1 state, the same for every agent):

| index | meaning                      |
| ----- | ---------------------------- |
| 0-2   | A position                   |
| 3-5   | D position                   |
| 6-8   | T position                   |
| 9-10  | A yaw, pitch (radians)       |
| 11-12 | D yaw, pitch                 |
| 13-14 | T yaw, pitch                 |
| 15-16 | T and D only: role one-hot (targeter, defender) |

The paper trains T and D as two agents; our shared team policy needs the role to tell
them apart, so T and D get two more numbers.

``rich`` (egocentric: vectors in the agent's *yaw frame* -- x ahead along its horizontal
heading, y to its left, z up -- and lengths divided by ``position_scale``). The game is
symmetric under rotations about the vertical axis through the terminal, so this view
loses nothing, and a turn toward something is a simple function of where it appears:

| index | meaning                                                   |
| ----- | --------------------------------------------------------- |
| 0-1   | own pitch: sin, cos                                       |
| 2-4   | first other: relative position (other - own)              |
| 5     | first other: distance                                     |
| 6-8   | first other: heading (unit vector)                        |
| 9-15  | second other: the same seven numbers                      |
| 16-18 | terminal relative to own position                         |
| 19    | distance to the terminal                                  |
| 20    | fraction of the time limit left, 1 at the start           |
| 21-22 | T and D only: role one-hot (targeter, defender)           |

With ``attacker_memory`` (both layouts), A's observation ends with one more number: the
largest turn T has made away from its line home so far in the game (the growth over one step
of the angle between T's heading and its line from the step's start to the terminal), as a
fraction of T's largest turn per step, in ``[0, 1]``. A T that flies at the terminal never turns
away from it; one that hides from an oncoming A does, and A remembers it after T turns back
(``BatchedGame.targeter_turned_away``, reset with the game).

"Others" come opponent first: A sees (T, D), T sees (A, D), D sees (A, T).

Global state (critic input, 22 numbers): positions of A, T, D (9, scaled); headings of A,
T, D as ``(cos yaw, sin yaw, pitch / (pi/2))`` (9: unlike a unit vector this keeps the
yaw at vertical pitch, so the state fixes the game exactly); distances A-T, D-A,
T-terminal (3, scaled); time left (1).

A learned policy's input is ``[own observation | global state]``: its actor reads the
first part, a centralized critic (and a scripted player hosted in RLlib) the second.
``policy_input`` builds it, ``split_policy_input`` takes it apart, ``policy_input_size``
gives its length from the config alone.
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from envs.agents import ATTACKER, DEFENDER, TARGETER
from envs.config import GameConfig
from envs.geometry import norm
from envs.kinematics import heading_vectors

PAPER_SIZE = 15
RICH_SIZE = 21
# Where the ``rich`` table's blocks start: an other's seven numbers are its relative position
# (+0..2), distance (+3) and heading (+4..6).
RICH_FIRST_OTHER = 2
RICH_SECOND_OTHER = 9
RICH_HEADING = 4
RICH_TERMINAL = 16
ROLE_SIZE = 2
GLOBAL_STATE_SIZE = 22
# Columns of the global state (layout in the module docstring).
STATE_D_ATTACKER, STATE_T_TERMINAL, STATE_TIME_LEFT = 19, 20, 21
# Whom each agent sees first and second: opponent first.
OTHERS = {ATTACKER: (TARGETER, DEFENDER), TARGETER: (ATTACKER, DEFENDER), DEFENDER: (ATTACKER, TARGETER)}
ROLE_ONE_HOT = {TARGETER: (1.0, 0.0), DEFENDER: (0.0, 1.0)}


def observation_size(config: GameConfig, agent: int) -> int:
    base = PAPER_SIZE if config.observation == "paper" else RICH_SIZE
    return base + int(config.attacker_memory) if agent == ATTACKER else base + ROLE_SIZE


def policy_input_size(config: GameConfig, agent: int) -> int:
    """Length of ``agent``'s policy input: its observation, then the global state."""
    return observation_size(config, agent) + GLOBAL_STATE_SIZE


def policy_input(observation: np.ndarray, state: np.ndarray) -> np.ndarray:
    """``[observation | global state]`` along the last axis (one game or a batch)."""
    return np.concatenate((observation, state), axis=-1)


# TorchScript compiles these two from the exported policies (league/evaluation/exported_policy.py) and knows no
# TypeVar nor Protocol: their array argument stays unannotated, which TorchScript reads as a Tensor.
def split_policy_input(inputs, own_size: int):  # type: ignore[no-untyped-def]
    """``(own observation, global state)`` of policy inputs: numpy arrays or torch tensors, any leading axes."""
    return inputs[..., :own_size], inputs[..., own_size:]


def role_of(observation):  # type: ignore[no-untyped-def]
    """The role one-hot that ends T's and D's own observation (numpy or torch, any leading axes)."""
    return observation[..., -ROLE_SIZE:]


def _with_role_or_memory(obs: np.ndarray, agent: int, memory: np.ndarray | None) -> np.ndarray:
    """T's and D's observation end with their role, A's with its memory where it has one."""
    if agent == ATTACKER:
        return obs if memory is None else np.concatenate((obs, memory[:, None]), axis=1)
    role = np.broadcast_to(np.asarray(ROLE_ONE_HOT[agent]), (obs.shape[0], ROLE_SIZE))
    return np.concatenate((obs, role), axis=1)


def observe(
    config: GameConfig,
    positions: np.ndarray,
    headings: np.ndarray,
    time_left: np.ndarray,
    agents: Sequence[int] = (ATTACKER, TARGETER, DEFENDER),
    targeter_turned_away: np.ndarray | None = None,
) -> list[np.ndarray]:
    """Observations of ``agents`` (default ``[attacker, targeter, defender]``), each ``(N, size)`` float32.

    ``targeter_turned_away`` ``(N,)``: A's memory (``BatchedGame.targeter_turned_away``), needed
    when ``config.attacker_memory``.
    """
    memory = None
    if config.attacker_memory:
        if targeter_turned_away is None:
            raise ValueError("game.attacker_memory: the attacker's observation needs targeter_turned_away")
        memory = np.asarray(targeter_turned_away, dtype=np.float64)
    if config.observation == "paper":
        shared = np.concatenate(
            (
                positions[:, ATTACKER],
                positions[:, DEFENDER],
                positions[:, TARGETER],
                headings[:, ATTACKER],
                headings[:, DEFENDER],
                headings[:, TARGETER],
            ),
            axis=1,
        )
        return [_with_role_or_memory(shared, agent, memory).astype(np.float32) for agent in agents]

    scaled = positions / config.position_scale
    vectors = heading_vectors(headings)
    out = []
    for agent in agents:
        own = scaled[:, agent]
        to_frame = yaw_frame(headings[:, agent, 0])
        pitch = headings[:, agent, 1]
        parts = [np.sin(pitch)[:, None], np.cos(pitch)[:, None]]
        for other in OTHERS[agent]:
            rel = scaled[:, other] - own
            parts += [to_frame(rel), norm(rel)[:, None], to_frame(vectors[:, other])]
        parts += [to_frame(-own), norm(own)[:, None], time_left[:, None]]
        out.append(_with_role_or_memory(np.concatenate(parts, axis=1), agent, memory).astype(np.float32))
    return out


def yaw_frame(yaw: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """A function taking world vectors ``(N, 3)`` into the frame turned by ``yaw`` about z."""
    cos, sin = np.cos(yaw)[:, None], np.sin(yaw)[:, None]

    def rotate(v: np.ndarray) -> np.ndarray:
        return np.concatenate((cos * v[:, :1] + sin * v[:, 1:2], -sin * v[:, :1] + cos * v[:, 1:2], v[:, 2:]), axis=1)

    return rotate


def global_state(config: GameConfig, positions: np.ndarray, headings: np.ndarray, time_left: np.ndarray) -> np.ndarray:
    """The centralized critic's input ``(N, 22)`` float32."""
    scaled = positions / config.position_scale
    distances = np.stack(
        (
            norm(scaled[:, ATTACKER] - scaled[:, TARGETER]),
            norm(scaled[:, DEFENDER] - scaled[:, ATTACKER]),
            norm(scaled[:, TARGETER]),
        ),
        axis=1,
    )
    n = positions.shape[0]
    yaw, pitch = headings[..., 0], headings[..., 1]
    angles = np.stack((np.cos(yaw), np.sin(yaw), pitch / (np.pi / 2)), axis=-1)
    parts = (scaled.reshape(n, 9), angles.reshape(n, 9), distances, time_left[:, None])
    return np.concatenate(parts, axis=1).astype(np.float32)


def terminal_distance(config: GameConfig, states: np.ndarray) -> np.ndarray:
    """T's distance to the terminal, read from global states (any leading axes)."""
    return np.asarray(states[..., STATE_T_TERMINAL], dtype=np.float64) * config.position_scale


def interception_distance(config: GameConfig, states: np.ndarray) -> np.ndarray:
    """D's distance to A, read from global states (any leading axes)."""
    return np.asarray(states[..., STATE_D_ATTACKER], dtype=np.float64) * config.position_scale


def decode_global_state(config: GameConfig, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(positions (N, 3, 3), headings (N, 3, 2), time_left (N,))`` back from global states."""
    states = np.asarray(states, dtype=np.float64)
    n = states.shape[0]
    positions = states[:, 0:9].reshape(n, 3, 3) * config.position_scale
    angles = states[:, 9:18].reshape(n, 3, 3)
    yaw = np.mod(np.arctan2(angles[..., 1], angles[..., 0]), 2 * np.pi)
    headings = np.stack((yaw, angles[..., 2] * (np.pi / 2)), axis=-1)
    return positions, headings, states[:, STATE_TIME_LEFT]

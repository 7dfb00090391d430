"""Turn-limited heading kinematics for N games of three agents at once.

A heading is ``(yaw phi, pitch theta)`` with unit vector
``(cos theta cos phi, cos theta sin phi, sin theta)``; yaw lives in ``[0, 2 pi)``,
pitch in ``[-pi/2, pi/2]``.

One step of one agent:

1. The commanded turn is clipped to ``|d phi| <= max_yaw_change`` and
   ``|d theta| <= max_pitch_change``.
2. The axis length ``L`` bounds the turn radius from below. A body moving a
   distance ``v`` on an arc of radius ``R`` turns by ``v / R``, so the heading may
   turn by at most ``v / L`` per step. The turn ``(d phi, d theta)`` is scaled down,
   keeping its direction, until ``sqrt(d phi^2 + d theta^2) <= v / L``: the angle
   between two headings is never larger than that length, so the bound holds exactly
   (it is conservative at high pitch, where yaw turns cost less angle). With the
   paper's numbers it binds for T only (``v_T / L = 1.3`` rad).
3. Pitch is clamped to ``[-pi/2, pi/2]``, yaw wrapped to ``[0, 2 pi)``.
4. The body moves the distance ``v`` along the circular arc that turns the old
   heading into the new one (radius ``v / angle``, never below ``L``; a straight
   line when the angle is 0). Speed along the path is therefore constant.
"""

from __future__ import annotations

import numpy as np

TWO_PI = 2.0 * np.pi
HALF_PI = 0.5 * np.pi
# Below this angle the arc is a straight line to float precision (sin x / x == 1).
STRAIGHT_ANGLE = 1e-8


def heading_vectors(headings: np.ndarray) -> np.ndarray:
    """Unit vectors ``(..., 3)`` of headings ``(..., 2)`` given as (yaw, pitch)."""
    phi, theta = headings[..., 0], headings[..., 1]
    cos_theta = np.cos(theta)
    return np.stack((cos_theta * np.cos(phi), cos_theta * np.sin(phi), np.sin(theta)), axis=-1)


def headings_of(vectors: np.ndarray, fallback_yaw: np.ndarray | float = 0.0) -> np.ndarray:
    """(yaw, pitch) of non-zero vectors ``(..., 3)``.

    Straight up or down the yaw is undefined; ``fallback_yaw`` is kept there.
    """
    x, y, z = vectors[..., 0], vectors[..., 1], vectors[..., 2]
    horizontal = np.hypot(x, y)
    pitch = np.arctan2(z, horizontal)
    yaw = np.where(horizontal > 1e-12, np.mod(np.arctan2(y, x), TWO_PI), fallback_yaw)
    return np.stack((yaw, pitch), axis=-1)


def wrap_to_pi(angle: np.ndarray) -> np.ndarray:
    """Angle difference folded into ``[-pi, pi)``."""
    return np.mod(angle + np.pi, TWO_PI) - np.pi


def turn(
    headings: np.ndarray,
    yaw_change: np.ndarray,
    pitch_change: np.ndarray,
    max_yaw: float,
    max_pitch: float,
    max_angle: np.ndarray | float = np.inf,
) -> np.ndarray:
    """Heading after a (yaw, pitch) change within the turn limits (steps 1 to 3 above).

    ``max_angle`` is ``v / L`` per body (broadcast over the last batch axis).
    """
    yaw_change = np.clip(yaw_change, -max_yaw, max_yaw)
    pitch_change = np.clip(pitch_change, -max_pitch, max_pitch)
    length = np.hypot(yaw_change, pitch_change)
    scale = np.minimum(1.0, max_angle / np.maximum(length, 1e-300))
    yaw = np.mod(headings[..., 0] + scale * yaw_change, TWO_PI)
    pitch = np.clip(headings[..., 1] + scale * pitch_change, -HALF_PI, HALF_PI)
    return np.stack((yaw, pitch), axis=-1)


def move(positions: np.ndarray, headings: np.ndarray, new_headings: np.ndarray, speeds: np.ndarray) -> np.ndarray:
    """New positions after moving every body ``speeds`` along its arc (step 4 above).

    Args:
        positions: ``(..., 3)`` positions at the start of the step.
        headings: ``(..., 2)`` headings at the start of the step.
        new_headings: ``(..., 2)`` headings at the end of the step (see ``turn``).
        speeds: distance per step, broadcastable to ``positions[..., 0]``.
    """
    start = heading_vectors(headings)
    end = heading_vectors(new_headings)
    cos_angle = np.clip((start * end).sum(axis=-1), -1.0, 1.0)
    angle = np.arccos(cos_angle)
    # Unit vector normal to `start` in the turning plane; zero when there is no turn.
    normal = end - cos_angle[..., None] * start
    normal_norm = np.linalg.norm(normal, axis=-1, keepdims=True)
    normal = np.divide(normal, normal_norm, out=np.zeros_like(normal), where=normal_norm > 1e-12)
    # Arc of length v and radius v / angle: chord components along start and normal.
    straight = angle < STRAIGHT_ANGLE
    safe = np.where(straight, 1.0, angle)
    along = np.where(straight, 1.0, np.sin(angle) / safe)
    across = np.where(straight, 0.0, (1.0 - cos_angle) / safe)
    return positions + speeds[..., None] * (along[..., None] * start + across[..., None] * normal)

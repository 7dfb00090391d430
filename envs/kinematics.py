"""Turn-limited heading kinematics for N games of three agents at once.

A heading is ``(yaw phi, pitch theta)`` with unit vector
``(cos theta cos phi, cos theta sin phi, sin theta)``; yaw lives in ``[0, 2 pi)``,
pitch in ``[-pi/2, pi/2]``.

One step of one agent:

1. The commanded turn is clipped to ``|d phi| <= max_yaw_change`` and
   ``|d theta| <= max_pitch_change``; then ``d theta`` is cut so that the pitch stays in
   ``[-pi/2, pi/2]`` (the pitch clamp).
2. The axis length ``L`` bounds the turn radius from below. A body moving a distance
   ``v`` on an arc of radius ``R`` turns by ``v / R``, so its heading may turn by at most
   ``v / L`` per step. The bound applies to the true angle between the old heading and
   the new one, after the clamp: where that angle exceeds ``v / L``, the turn
   ``(d phi, d theta)`` is scaled by the ``c`` in ``(0, 1)`` at which it is exactly
   ``v / L`` (bracketed Newton's method, to ``TURN_ANGLE_TOLERANCE`` = 1e-12 rad).
   Scaling keeps the direction of the command and the yaw and pitch limits. With the
   paper's numbers it binds for T only (``v_T / L = 1.3`` rad, while a full yaw command
   turns T by pi/2); A and D turn at most ~1.72 rad, below ``v_A / L = 1.8``.
   ``axis_length = 0`` leaves ``L`` out: the paper's explicit yaw and pitch limits alone.
3. Yaw is wrapped to ``[0, 2 pi)``.
4. The body moves the distance ``v`` along the circular arc that turns the old heading
   into the new one, in the plane of the two headings (radius ``v / angle``, never below
   ``L``; a straight line when the angle is 0). Speed along the path is constant, and
   the heading turns at a constant rate, so at fraction ``s`` of the step the body is at
   ``p + v s S(a s) u + v s (a s / 2) S(a s / 2)^2 n`` with ``a`` the angle, ``u`` the old
   heading, ``n`` the unit normal toward the new one and ``S(x) = sin(x) / x``
   (``Arcs.at``). An exact U-turn (antipodal headings, possible only when
   ``max_yaw_change = pi``) has no plane of its own: it turns in the plane of the old
   heading and the heading halfway through the command.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envs.geometry import dot

TWO_PI = 2.0 * np.pi
HALF_PI = 0.5 * np.pi
# Newton's method stops once the angle is this close to v / L (radians), after one more step.
TURN_ANGLE_TOLERANCE = 1e-12
MAX_SCALE_STEPS = 100
# sin(x) / x is 1 - x^2 / 6 to float precision below this.
SMALL_ANGLE = 1e-4
# |sin(angle)| below this: headings equal or opposite, the normal comes from the command.
PARALLEL = 1e-12
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


def _sin_over(x: np.ndarray) -> np.ndarray:
    """``sin(x) / x``, 1 at 0."""
    small = np.abs(x) < SMALL_ANGLE
    ratio: np.ndarray = np.where(small, 1.0 - x * x / 6.0, np.sin(x) / np.where(small, 1.0, x))
    return ratio


def _haversine(pitch: np.ndarray, yaw_change: np.ndarray, pitch_change: np.ndarray) -> np.ndarray:
    """``sin^2(a / 2)`` of the angle ``a`` between ``(phi, pitch)`` and ``(phi + yaw_change, pitch + pitch_change)``.

    Haversine form, accurate for small and large angles:
    ``sin^2(a / 2) = sin^2(d theta / 2) + cos(theta) cos(theta') sin^2(d phi / 2)``.
    """
    yaw_term = np.cos(pitch) * np.cos(pitch + pitch_change) * np.sin(0.5 * yaw_change) ** 2
    sin2_half_angle: np.ndarray = np.sin(0.5 * pitch_change) ** 2 + yaw_term
    return sin2_half_angle


def turn_angle(pitch: np.ndarray, yaw_change: np.ndarray, pitch_change: np.ndarray) -> np.ndarray:
    """True angle between heading ``(phi, pitch)`` and ``(phi + yaw_change, pitch + pitch_change)``."""
    angle: np.ndarray = 2.0 * np.arcsin(np.sqrt(np.clip(_haversine(pitch, yaw_change, pitch_change), 0.0, 1.0)))
    return angle


def _scale_to_angle(
    pitch: np.ndarray, yaw_change: np.ndarray, pitch_change: np.ndarray, full: np.ndarray, target: np.ndarray
) -> np.ndarray:
    """A ``c`` in ``(0, 1)`` with ``turn_angle(pitch, c d phi, c d theta) = target < pi`` (step 2).

    ``full`` is ``sin^2(angle / 2)`` of the whole turn (``c = 1``). Newton's method on
    ``h(c) = sin^2(angle / 2)``, kept inside a bracket ``[lo, hi]`` (the angle below the
    target at ``lo``, above it at ``hi``; a step that leaves it bisects instead), from
    ``c = target / angle(1)``: exact when the angle grows linearly in ``c`` (a pure yaw
    turn at pitch 0, a pure pitch turn), close otherwise; then one more Newton step. Near
    a pole the angle need not grow monotonically in ``c``; the bracket still ends on a root.
    """
    goal = np.sin(0.5 * target) ** 2
    # |h - goal| <= tolerance puts the angle within TURN_ANGLE_TOLERANCE (dh / da = sin(a) / 2).
    tolerance = np.maximum(0.5 * np.sin(target) * TURN_ANGLE_TOLERANCE, 1e-16)
    cos_pitch, sin_pitch = np.cos(pitch), np.sin(pitch)
    lo, hi = np.zeros_like(target), np.ones_like(target)
    c = 0.5 * target / np.arcsin(np.sqrt(full))
    # Each turn's result is fixed when it converges, whatever its neighbours still do, so a
    # game's result does not depend on the other games in the batch.
    scale, finished = np.zeros_like(target), np.zeros(target.shape, dtype=bool)
    for _ in range(MAX_SCALE_STEPS):
        half_pitch, half_yaw = 0.5 * c * pitch_change, 0.5 * c * yaw_change
        sin_p, cos_p, sin_y, cos_y = np.sin(half_pitch), np.cos(half_pitch), np.sin(half_yaw), np.cos(half_yaw)
        cos_step, sin_step = 1.0 - 2.0 * sin_p * sin_p, 2.0 * sin_p * cos_p  # of c * d theta
        cos_new = cos_pitch * cos_step - sin_pitch * sin_step  # cos(theta + c d theta)
        sin_new = sin_pitch * cos_step + cos_pitch * sin_step
        yaw_term = cos_pitch * sin_y * sin_y
        excess = sin_p * sin_p + cos_new * yaw_term - goal
        slope = (sin_p * cos_p - sin_new * yaw_term) * pitch_change + cos_pitch * cos_new * sin_y * cos_y * yaw_change
        hi, lo = np.where(excess > 0, c, hi), np.where(excess < 0, c, lo)
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = c - excess / slope
        inside = (newton > lo) & (newton < hi)
        done = ~finished & (np.abs(excess) <= tolerance)
        scale = np.where(done, np.where(inside, newton, c), scale)  # one more Newton step: exact to rounding
        finished |= done
        if finished.all():
            return scale
        c = np.where(inside, newton, 0.5 * (lo + hi))
    return np.where(finished, scale, lo)  # not reached in practice: bisection alone gets there in ~50 steps


def limit_turn(
    headings: np.ndarray,
    yaw_change: np.ndarray,
    pitch_change: np.ndarray,
    max_yaw: float,
    max_pitch: float,
    max_angle: np.ndarray | float = np.inf,
) -> np.ndarray:
    """The (yaw, pitch) change ``(..., 2)`` a command really makes (steps 1 and 2 above).

    ``max_angle`` is ``v / L`` per body (broadcast over the last batch axis); ``inf``
    leaves the axis length out.
    """
    pitch = headings[..., 1]
    # np.minimum / np.maximum: the same as np.clip, at half its cost on small arrays.
    yaw_change = np.minimum(np.maximum(yaw_change, -max_yaw), max_yaw)
    pitch_change = np.minimum(np.maximum(pitch_change, -max_pitch), max_pitch)
    pitch_change = np.minimum(np.maximum(pitch + pitch_change, -HALF_PI), HALF_PI) - pitch
    change = np.stack((yaw_change, pitch_change), axis=-1)
    max_angle = np.broadcast_to(max_angle, pitch.shape)
    # The angle is at most the length of (d phi, d theta) (the sphere's metric is
    # d theta^2 + cos^2 theta d phi^2), and never above pi: only these turns may bind.
    maybe = (yaw_change**2 + pitch_change**2 > max_angle**2) & (max_angle < np.pi)
    if not maybe.any():
        return change
    rows = np.nonzero(maybe)
    pitch, yaw_change, pitch_change, max_angle = pitch[rows], yaw_change[rows], pitch_change[rows], max_angle[rows]
    full = _haversine(pitch, yaw_change, pitch_change)
    binding = full > np.sin(0.5 * max_angle) ** 2
    if binding.any():
        scale = _scale_to_angle(
            pitch[binding], yaw_change[binding], pitch_change[binding], full[binding], max_angle[binding]
        )
        change[tuple(axis[binding] for axis in rows)] *= scale[:, None]
    return change


def turned(headings: np.ndarray, change: np.ndarray) -> np.ndarray:
    """Headings after a change from ``limit_turn`` (step 3): yaw wrapped, pitch in range."""
    yaw = np.mod(headings[..., 0] + change[..., 0], TWO_PI)
    pitch = np.minimum(np.maximum(headings[..., 1] + change[..., 1], -HALF_PI), HALF_PI)  # only rounding to undo
    return np.stack((yaw, pitch), axis=-1)


@dataclass(frozen=True)
class Arcs:
    """The circular arcs bodies fly in one step (step 4 above), batched over leading axes."""

    start: np.ndarray  # (..., 3) positions at the start of the step
    tangent: np.ndarray  # (..., 3) unit heading at the start
    normal: np.ndarray  # (..., 3) unit normal toward the new heading in the turning plane (~0 without a turn)
    angle: np.ndarray  # (...,) heading change over the step, radians in [0, pi]
    speed: np.ndarray  # (...,) path length per step
    end: np.ndarray  # (..., 3) positions at the end of the step (``at(1)``)
    end_tangent: np.ndarray  # (..., 3) unit heading at the end of the step

    @classmethod
    def of_turn(
        cls,
        positions: np.ndarray,
        headings: np.ndarray,
        new_headings: np.ndarray,
        change: np.ndarray,
        speeds: np.ndarray,
        start: np.ndarray | None = None,
    ) -> "Arcs":
        """Arcs of bodies at ``positions`` turning from ``headings`` to ``new_headings``.

        ``change`` is the turn from ``limit_turn`` (``new_headings = turned(headings,
        change)``); it picks the plane of an exact U-turn. ``start`` may pass
        ``heading_vectors(headings)`` if the caller has them.
        """
        start = heading_vectors(headings) if start is None else start
        end = heading_vectors(new_headings)
        cos_angle = dot(start, end)
        normal = end - cos_angle[..., None] * start
        sin_angle = np.sqrt(dot(normal, normal))
        angle = np.arctan2(sin_angle, cos_angle)
        speed = np.broadcast_to(speeds, angle.shape)
        parallel = sin_angle < PARALLEL
        normal /= np.where(parallel, 1.0, sin_angle)[..., None]  # ~zero where the heading does not turn
        # The chord: v sin(a) / a along u, v (1 - cos a) / a across, which is
        # v tan(a / 2) / a (u + e) = v sin(a) / (a (1 + cos a)) (u + e), e the new heading.
        sin_over_angle = np.where(angle > STRAIGHT_ANGLE, sin_angle / np.where(angle > 0, angle, 1.0), 1.0)
        chord = speed * sin_over_angle / (1.0 + np.maximum(cos_angle, -0.5))  # U-turns are redone below
        end_positions = positions + chord[..., None] * (start + end)
        u_turn = parallel & (cos_angle < 0)
        if u_turn.any():  # opposite headings: the plane of the heading halfway through the command
            rows = np.nonzero(u_turn)
            halfway = heading_vectors(headings[rows] + 0.5 * change[rows])
            halfway -= dot(halfway, start[rows])[..., None] * start[rows]
            normal[rows] = halfway / np.sqrt(dot(halfway, halfway))[..., None]
            end_positions[rows] = positions[rows] + (2.0 / np.pi) * speed[rows][..., None] * normal[rows]
        return cls(positions, start, normal, angle, speed, end_positions, end)

    def take(self, index: np.ndarray | tuple[np.ndarray, ...]) -> "Arcs":
        """The arcs at ``index`` (anything that indexes the leading axes)."""
        fields = (self.start, self.tangent, self.normal, self.angle, self.speed, self.end, self.end_tangent)
        return Arcs(*(field[index] for field in fields))

    def at(self, fraction: np.ndarray | float, rows: np.ndarray | None = None) -> np.ndarray:
        """Positions ``(..., 3)`` at ``fraction`` of the step; extra leading axes of ``fraction`` broadcast.

        ``rows`` picks arcs along the first axis (the same as ``take(rows).at(fraction)``).
        """
        start, tangent, normal, angle, speed = self.start, self.tangent, self.normal, self.angle, self.speed
        if rows is not None:
            start, tangent, normal, angle, speed = start[rows], tangent[rows], normal[rows], angle[rows], speed[rows]
        x = angle * fraction
        along = speed * fraction * _sin_over(x)
        across = speed * fraction * 0.5 * x * _sin_over(0.5 * x) ** 2
        positions: np.ndarray = start + along[..., None] * tangent + across[..., None] * normal
        return positions

    @property
    def bow(self) -> np.ndarray:
        """Bound on how far the path strays from its chord, over any fraction ``w`` of the step: ``bow * w^2``.

        The path's acceleration is ``v a`` (speed ``v`` on radius ``v / a``); a curve whose
        second derivative is at most ``M`` strays at most ``M / 8`` from its chord.
        """
        bound: np.ndarray = self.speed * self.angle / 8.0
        return bound


def move(positions: np.ndarray, headings: np.ndarray, change: np.ndarray, speeds: np.ndarray) -> np.ndarray:
    """New positions after every body flies ``speeds`` along its arc, turning by ``change`` (step 4 above)."""
    return Arcs.of_turn(positions, headings, turned(headings, change), change, speeds).end

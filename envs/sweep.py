"""When, within one step, two bodies flying their arcs first come within a radius.

Closing speeds reach 0.36 per step, twice the capture radius, so a capture must be looked
for over the whole step, and along the paths the bodies really fly: the circular arcs of
``envs.kinematics``. A hard turn bows an arc up to ~0.034 off its chord, enough to decide
~2% of scripted games differently, so sweeping the chords is not good enough.

Method, for all pairs of all games at once. Let ``r(s)`` be the pair's relative position
at fraction ``s`` of the step.

1. Over an interval of width ``w``, ``r`` strays from its chord by at most ``B w^2``,
   ``B = (v_1 a_1 + v_2 a_2) / 8`` (``Arcs.bow``: speed times turn angle over 8, for each
   body). So where the chord's closest approach is farther than ``radius + B w^2`` the
   pair cannot touch in that interval, and where it is nearer than ``radius - B w^2`` it
   surely does.
2. Start from the whole step; split every interval that may hold a contact into
   ``SPLIT`` parts and test each part again, dropping the parts after the first part that
   surely holds a contact. Stop when ``B w^2 <= TOLERANCE`` (at most five rounds with the
   paper's speeds and turn limits).
3. The contact time is where the chord of the first remaining part meets the radius.

Guarantee: a pair whose paths come within ``radius - 2 TOLERANCE`` is always reported, one
that stays farther than ``radius + 2 TOLERANCE`` never is; at the reported time the true
distance is within ``TOLERANCE`` of the radius, and no earlier time in the step has it below
``radius - 2 TOLERANCE``. A pair already within the radius at the start reports 0.
``tests/envs/test_sweep.py`` checks this against thousands of sub-steps.
"""

from __future__ import annotations

import numpy as np

from envs.geometry import dot, first_contact
from envs.kinematics import Arcs

# Distance tolerance of the sweep, in the game's length unit (positions are ~1 to 10).
TOLERANCE = 1e-9
# Parts each uncertain interval is split into per round.
SPLIT = 8
_STEPS = np.arange(SPLIT + 1)


def _chord_distance(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Closest distance to the origin of the segments ``start -> end`` ``(..., 3)``."""
    delta = end - start
    length2 = dot(delta, delta)
    along = np.clip(-dot(start, delta) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
    closest = start + along[..., None] * delta
    distance: np.ndarray = np.sqrt(dot(closest, closest))
    return distance


def _pick(arcs: Arcs, game: np.ndarray, body: np.ndarray) -> Arcs:
    """Arcs of ``body`` in ``game``, one per row; body index ``B`` (one past the last) is the origin at rest."""
    resting = body == arcs.angle.shape[1]
    picked = arcs.take((game, np.where(resting, 0, body)))
    moving = ~resting
    start, end = picked.start * moving[:, None], picked.end * moving[:, None]
    angle, speed = picked.angle * moving, picked.speed * moving
    return Arcs(start, picked.tangent, picked.normal, angle, speed, end, picked.end_tangent)


def first_contact_on_arcs(arcs: Arcs, pairs: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Earliest fraction of the step at which each pair is within its radius, ``inf`` if never.

    Args:
        arcs: the bodies' arcs, fields ``(N games, B bodies, ...)``.
        pairs: ``(K, 2)`` body indices; a second index ``B`` stands for the origin, at rest.
        radius: ``(K,)`` contact radius of each pair.

    Returns ``(N, K)``.
    """
    one, other = pairs[:, 0], pairs[:, 1]
    resting = other == arcs.angle.shape[1]
    other_body, moving = np.where(resting, 0, other), (~resting).astype(np.float64)

    def relative(field: np.ndarray) -> np.ndarray:  # (N, K, ...): one minus other
        difference: np.ndarray = np.take(field, one, axis=1) - np.take(field, other_body, axis=1) * moving[:, None]
        return difference

    # A body flies at most its speed in a step: pairs farther apart than the radius plus
    # both speeds cannot touch (most pairs, most steps).
    separation = relative(arcs.start)
    reach = radius + np.take(arcs.speed, one, axis=1) + np.take(arcs.speed, other_body, axis=1) * moving
    contact = np.full(reach.shape, np.inf)
    game, pair = np.nonzero(dot(separation, separation) <= reach * reach)
    if not len(game):
        return contact
    first, second = _pick(arcs, game, one[pair]), _pick(arcs, game, other[pair])
    start, end, bow = first.start - second.start, first.end - second.end, first.bow + second.bow
    near = _chord_distance(start, end) <= radius[pair] + bow
    if near.any():
        contact[game[near], pair[near]] = _refine(
            first.take(near), second.take(near), start[near], end[near], bow[near], radius[pair[near]]
        )
    return contact


def _refine(
    first: Arcs, second: Arcs, start: np.ndarray, end: np.ndarray, bow: np.ndarray, radius: np.ndarray
) -> np.ndarray:
    """Steps 2 and 3 for candidate pairs ``(C,)`` whose chord over the whole step may touch."""
    contact = np.full(bow.shape, np.inf)
    # One row per interval still in question: its candidate, its start, its chord's ends.
    rows, lo = np.arange(len(bow)), np.zeros(len(bow))
    width = 1.0
    while len(rows):
        # Rows whose chords are their paths to the tolerance end here (each on its own, so a
        # pair's result does not depend on the other pairs in the batch).
        final = width * width * bow[rows] <= TOLERANCE
        if final.any():
            tau = first_contact(start[final], end[final], radius[rows[final]])
            np.minimum.at(contact, rows[final], lo[final] + width * tau)
            rows, lo, start, end = rows[~final], lo[~final], start[~final], end[~final]
            if not len(rows):
                break
        width /= SPLIT
        fractions = (lo[:, None] + width * _STEPS).T  # (SPLIT + 1, rows)
        points = first.at(fractions, rows) - second.at(fractions, rows)
        start, end = points[:-1], points[1:]  # (SPLIT, rows, 3): the parts' chords
        distance = _chord_distance(start, end)
        margin = bow[rows] * width * width
        maybe = distance <= radius[rows] + margin
        # The first part that surely holds a contact ends the search for its candidate.
        cutoff = np.full(bow.shape, np.inf)
        np.minimum.at(cutoff, rows, np.where(distance <= radius[rows] - margin, fractions[1:], np.inf).min(axis=0))
        part, row = np.nonzero(maybe & (fractions[:-1] < cutoff[rows]))
        rows, lo, start, end = rows[row], fractions[part, row], start[part, row], end[part, row]
    return contact

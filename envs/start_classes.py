"""What the geometry decides before anyone moves: each start is a T-race, A-certain or contested.

A start is classified on straight-line motion, instant turns and constant speeds (the
game's ``v_A``, ``v_T``, ``v_D`` of ``GameConfig``), with the game's radii: A captures T
within ``r_A`` (``attacker_radius``), D captures A within ``r_D`` (``defender_radius``),
T is home within ``r_ter`` (``terminal_sphere_radius``) of the origin. A body *reaches* a
point ``X`` when it gets there flying straight at its speed: T at ``|X - T| / v_T``; A
*captures T at* ``X`` once within ``r_A`` of it, at ``(|X - A| - r_A) / v_A``; D *covers*
``X`` once within ``r_D`` of it, at ``(|X - D| - r_D) / v_D``. Times are in steps and
continuous (not rounded to whole steps). The turn limits, the axis length and the time limit
play no part.

* ``t_race``: T's straight path to the terminal stays out of A's reach. T flies
  ``s`` in ``[0, S]``, ``S = |T| - r_ter`` (it is home at the terminal sphere, not at the
  origin), and ``min_s |A - T(s)| - r_A - (v_A / v_T) s > 0``. The expression falls along
  the whole path (``|A - T(s)|`` changes at most at rate 1, the last term grows at
  ``v_A / v_T > 1``), so the minimum is at ``s = S``: A cannot be within ``r_A`` of the
  point where T enters the terminal sphere when T gets there (``race_margin``, a length).
* ``a_certain``: not ``t_race``, and T has no *refuge*: no point ``X`` that T reaches
  before A can capture it there, ``|X - T| / v_T < (|X - A| - r_A) / v_A``, and that D
  covers no later than A reaches it, ``(|X - D| - r_D) / v_D <= |X - A| / v_A``
  (``refuge_margin``, in steps: the least ``(|X - D| - r_D) / v_D - |X - A| / v_A`` over
  T's region, ``> 0`` for no refuge). With A within ``r_A`` of T at the start, T's region
  is empty: ``a_certain``.
* ``contested``: the rest.

How ``X`` is searched. T's region ``{X : |X - T| / v_T < (|X - A| - r_A) / v_A}`` is
star-shaped about T (along a ray from T the left side grows at ``1 / v_T``, the right
at most at ``1 / v_A``, which is smaller), and on each ray its boundary is the positive
root of a quadratic, found exactly. The region is an oval of revolution (a quartic surface)
and the least D margin over it has no simple closed form, so ``refuge_margin`` takes the
least over a dense sample: ``DIRECTIONS`` = 2048 rays from T (a Fibonacci sphere,
neighbours about 0.08 rad apart), each at ``RADIAL_STEPS + 1`` = 9 points from T to the
boundary (the boundary point itself, the closure of the region, is included). Every sampled
point lies in T's region (or on its edge) and its D margin is exact, so the sample never
invents a refuge; it can only miss one thinner than its spacing, which would call a
contested start ``a_certain``. With ``v_D = v_A`` the
margin ``|X - D| - |X - A|`` has no minimum inside the region except on the ray from A
beyond D, so the least lies on the boundary and the rays matter most. On the ``default``
set's 1000 dev games the counts are the same from 2000 to 20,000 rays and with 1 to 40
points a ray; 200 rays miss one refuge.

The issue that asked for this ("Opponents from the theory") counted T-race 126,
A-certain 70, contested 804 on those games. This module counts 126, 68, 806: the
difference is games 26 and 407, whose refuges are thin slivers at the edge of T's region
(about 1e-5 and 7e-5 of the sampled region; D covers them 0.07 and 0.18 steps before A
gets there). A regular grid of candidate points 0.2 apart misses both and gives 70; 0.1
apart finds both. Every scripted attacker wins both games against the paper's team.
"""

from __future__ import annotations

from enum import StrEnum

import numpy as np

from envs.agents import ATTACKER, DEFENDER, TARGETER
from envs.config import GameConfig
from envs.geometry import dot, norm

DIRECTIONS = 2048
"""Rays from T along which T's region is searched for a refuge."""
RADIAL_STEPS = 8
"""Points per ray after T itself, evenly spaced up to the region's boundary."""
_POINTS_PER_CHUNK = 2_000_000  # candidate points held at once (48 MB per array of them)


class StartClass(StrEnum):
    """What the geometry says about a start (module docstring)."""

    T_RACE = "t_race"
    A_CERTAIN = "a_certain"
    CONTESTED = "contested"


def sphere_directions(n: int) -> np.ndarray:
    """``n`` unit vectors ``(n, 3)`` spread evenly over the sphere (a Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (1.0 + np.sqrt(5.0)) * i
    r = np.sqrt(1.0 - z * z)
    return np.stack((r * np.cos(phi), r * np.sin(phi), z), axis=-1)


def race_margin(positions: np.ndarray, config: GameConfig) -> np.ndarray:
    """``min_s |A - T(s)| - r_A - (v_A / v_T) s`` along T's straight path home, ``(N,)``.

    ``positions`` ``(N, 3 agents, 3)`` in agent order. The minimum is at the path's end,
    ``s = S = max(|T| - r_ter, 0)`` (module docstring); ``> 0`` is a T-race.
    """
    attacker, targeter = positions[:, ATTACKER], positions[:, TARGETER]
    distance = norm(targeter)
    flight = np.maximum(distance - config.terminal_sphere_radius, 0.0)
    scale = np.divide(distance - flight, distance, out=np.zeros_like(distance), where=distance > 0)
    home = targeter * scale[:, None]  # where T enters the terminal sphere
    return norm(attacker - home) - config.attacker_radius - config.v_attacker / config.v_targeter * flight


def region_radius(targeter: np.ndarray, attacker: np.ndarray, directions: np.ndarray, config: GameConfig) -> np.ndarray:
    """Distance from T along each unit direction to the edge of T's region.

    The arguments broadcast over their leading axes (positions ``(N, 1, 3)`` with directions
    ``(1, M, 3)`` give ``(N, M)``; ``(N, 3)`` with ``(N, 3)``, one direction per game, ``(N,)``).
    The edge solves ``rho / v_T = (|T - A + rho w| - r_A) / v_A``; squared, with
    ``k = v_T / v_A`` and ``d = T - A``:
    ``(1/k^2 - 1) rho^2 + 2 (r_A / k - d.w) rho + r_A^2 - |d|^2 = 0``, whose one positive root
    it is when ``|d| > r_A``. 0 where A is already within ``r_A`` of T (an empty region).
    """
    k = config.v_targeter / config.v_attacker
    r = config.attacker_radius
    d = targeter - attacker
    a = 1.0 / (k * k) - 1.0
    b = 2.0 * (r / k - dot(d, directions))
    c = r * r - dot(d, d)
    rho = (-b + np.sqrt(np.maximum(b * b - 4.0 * a * c, 0.0))) / (2.0 * a)
    return np.where(c < 0, rho, 0.0)


def refuge_margin(
    positions: np.ndarray, config: GameConfig, directions: int = DIRECTIONS, radial_steps: int = RADIAL_STEPS
) -> np.ndarray:
    """Least ``(|X - D| - r_D) / v_D - |X - A| / v_A`` (steps) over T's region, ``(N,)``.

    ``<= 0``: T has a refuge that D covers no later than A arrives; ``+inf`` where the region
    is empty. Searched on ``directions`` rays from T at ``radial_steps + 1`` points each.
    """
    rays = sphere_directions(directions)
    fractions = np.linspace(0.0, 1.0, radial_steps + 1)
    chunk = max(1, _POINTS_PER_CHUNK // directions)
    margins = []
    for start in range(0, len(positions), chunk):
        part = positions[start : start + chunk]
        attacker, targeter, defender = part[:, ATTACKER, None], part[:, TARGETER, None], part[:, DEFENDER, None]
        rho = region_radius(targeter, attacker, rays[None], config)
        least = np.full(len(part), np.inf)
        for fraction in fractions:
            x = targeter + (fraction * rho)[..., None] * rays
            d_time = (norm(x - defender) - config.defender_radius) / config.v_defender
            slack = d_time - norm(x - attacker) / config.v_attacker
            least = np.minimum(least, np.where(rho > 0, slack, np.inf).min(axis=1))
        margins.append(least)
    return np.concatenate(margins) if margins else np.zeros(0)


def classify(
    positions: np.ndarray, config: GameConfig, directions: int = DIRECTIONS, radial_steps: int = RADIAL_STEPS
) -> np.ndarray:
    """The ``StartClass`` value of each start ``(N, 3 agents, 3)``, as an array of strings ``(N,)``."""
    race = race_margin(positions, config) > 0
    refuge = refuge_margin(positions, config, directions, radial_steps) <= 0
    not_race = np.where(refuge, StartClass.CONTESTED.value, StartClass.A_CERTAIN.value)
    return np.where(race, StartClass.T_RACE.value, not_race)


def class_counts(classes: np.ndarray) -> dict[StartClass, int]:
    """How many starts of each class, every class listed (``classify``'s output)."""
    return {c: int(np.sum(classes == c.value)) for c in StartClass}


def win_rates_by_class(wins: np.ndarray, classes: np.ndarray) -> dict[StartClass, float | None]:
    """Fraction of each class's starts where ``wins`` ``(N,)`` is true; ``None`` for a class without starts."""
    return {c: float(wins[classes == c.value].mean()) if np.any(classes == c.value) else None for c in StartClass}

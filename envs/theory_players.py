"""Scripted players from the differential games of simple motion, lifted to this game.

The theory assumes *simple motion*: constant speeds ``v_A > v_T`` (``v_D`` any), instant
turns, straight flight to an aim point that is recomputed at every instant (a feedback
strategy). The game has turn limits (``max_yaw_change``, ``max_pitch_change``, the axis
length), whole steps and capture *radii* (``r_A``: A captures T, ``r_D``: D captures A,
``r_ter``: T is home), so here every aim point is recomputed at every step from the
current positions and the turn limits make the players only approximately optimal.
``k = v_T / v_A < 1`` throughout; every speed and radius is ``GameConfig``'s.

Attacker ``apollonius`` (target guarding: Isaacs' game, in 3D Yan et al. arXiv 2109.07075).

1. T's straight path home is ``P(s) = T + s u``, ``u = -T / |T|``, ``s`` in ``[0, S]``,
   ``S = |T| - r_ter``. A, flying straight, captures T at ``P(s)`` when
   ``(|P(s) - A| - r_A) / v_A <= s / v_T``; the difference of the two sides only falls
   along the path (its slope is at most ``1 / v_A - 1 / v_T < 0``), so A is in time on
   ``[rho, inf)``, ``rho`` the positive root of
   ``(1/k^2 - 1) rho^2 + 2 (r_A / k - (T - A).u) rho + r_A^2 - |T - A|^2 = 0``
   (``envs.start_classes.region_radius``). ``P(rho)`` is
   where T's path home leaves its Apollonius region (the Apollonius sphere of centre
   ``(T - k^2 A) / (1 - k^2)`` and radius ``k |T - A| / (1 - k^2)``, arXiv 2202.13522,
   with the capture radius folded in): a T flying straight home is met there.
2. A aims at the first of these whose straight approach D does not cut off: T's earliest
   interception point on its *current* course (``envs.geometry.lead_intercept``: T at its
   current velocity; the same point on a straight flight home, as T's region is that
   Apollonius sphere), then ``P(s)`` for ``s`` from ``rho`` to ``S`` (``APPROACH_CANDIDATES``
   points). D cuts off an approach when it covers a point ``Y`` of the segment
   ``A -> aim`` first, ``(|Y - D| - r_D) / v_D <= |Y - A| / v_A`` (checked at
   ``PATH_POINTS`` points; with ``v_D = v_A`` A's side of that surface, the inside of a
   hyperboloid sheet about A, is convex, so the end point decides). A later point of the
   path home is still in time (step 1) and nearer the terminal: A waits for T there, out
   of D's reach. While T shelters behind D, ``P(s)`` stays between T and the terminal: A
   guards the terminal, and a timeout is A's win.
3. If D cuts off every approach, A flies at ``P(min(rho, S))`` (``P(S)`` where T wins the
   straight race home, ``rho > S``): fleeing would open the terminal to T.

Team ``active_defense`` + ``active_defense`` (active target defense: Garcia, Casbeer and
Pachter, arXiv 2002.04054; the tutorial arXiv 2003.05013, its TAD section). In the theory
the T/D team wins when the A/D boundary (the points A and D reach at the same time: the
bisector plane of A and D when ``v_D = v_A``) cuts T's Apollonius ball against A, and the
saddle point of the game of degree (payoff: T's distance from A when D intercepts A) has A
and D fly to ``I* = argmin_I |I - T| + k |I - A|`` over that boundary, T straight away from
``I*``. The lift:

* the radii are folded in by moving each pursuer along its line of sight by its radius:
  ``A_r = A + r_A (T - A) / |T - A|`` for T's ball (centre ``c = (T - k^2 A_r) / (1 - k^2)``,
  radius ``R = k |T - A_r| / (1 - k^2)``), ``D_r = D + r_D (A - D) / |A - D|`` for the
  boundary (exact on those lines, approximate off them; ``envs.start_classes`` keeps the
  radii exactly);
* the boundary is taken as the plane through the point ``M`` of the segment ``D_r -> A``
  that both reach at the same time, ``M = D_r + v_D / (v_D + v_A) (A - D_r)``, with normal
  ``n = (A - D_r) / |A - D_r|``: the bisector plane when ``v_D = v_A`` (the game's
  default), the tangent plane of D's Apollonius sphere at ``M`` otherwise;
* the game's T wants the terminal, and a timeout is A's win, which the theory does not
  have: a T that ran from ``I*``, or hid from an attacker that never comes, lost 0.43 to
  0.51 of the 1000 ``default`` dev games to ``evade_defender`` on time. So T flies home
  whenever A is not flying toward it (``avoid_oncoming_attacker``'s rule), and otherwise at
  the point of its ball deepest into D's side rather than away from ``I*``: with D
  ``active_defense``, lead intercept won 0.484 of those games against it, 0.615 against a
  T running from ``I*``, 0.757 against a T flying at its refuge nearest the terminal (the
  point of ``B ∩ {(X - M).n <= 0}`` nearest the origin, a point of its edge).

Targeter ``active_defense``:

1. flies straight home when the straight race is won (``envs.start_classes.race_margin``
   ``> 0`` at the current positions: the T-race class) or A's velocity has no component
   toward T;
2. otherwise flies at ``c - R n``, the point of its ball deepest into D's side: the
   argument of the team's margin in the game of kind (``R - (c - M).n``, positive when D's
   side of the plane cuts T's ball; with no such cut, the least bad point).

Defender ``active_defense``: flies at ``I*`` on the plane. ``|I - T| + k |I - A|`` is convex
and, by symmetry, least on the line where the plane meets the plane of ``T``, ``A`` and
``n``, between the projections ``T_p`` and ``A_p`` of T and A; found by ``BISECTIONS``
bisections of its slope along ``T_p -> A_p``. With T on A's side of the plane (A need not
cross it to reach T) D flies at A.
"""

from __future__ import annotations

import numpy as np

from envs.agents import ATTACKER, DEFENDER, TARGETER
from envs.game_view import GameView
from envs.geometry import dot, lead_intercept, norm, unit
from envs.kinematics import heading_vectors
from envs.start_classes import race_margin, region_radius

APPROACH_CANDIDATES = 8
"""Aim points the Apollonius attacker tries on T's path home, from ``rho`` to ``S`` (after the lead point)."""
PATH_POINTS = 6
"""Points of A's straight approach checked against D's reach (the aim point included)."""
BISECTIONS = 30
"""Bisections for ``I*`` along ``T_p -> A_p`` (the segment's length over 2^30)."""


def home_path_meeting(game: GameView) -> tuple[np.ndarray, np.ndarray]:
    """``(rho, S)`` ``(N,)``: where A, flying straight, first captures T on T's straight path
    home, and where that path enters the terminal sphere, as distances from T (step 1)."""
    cfg = game.config
    a, t = game.positions[:, ATTACKER], game.positions[:, TARGETER]
    home = unit(-t)
    rho = region_radius(t, a, home, cfg)
    flight = np.maximum(norm(t) - cfg.terminal_sphere_radius, 0.0)
    return rho, flight


def attacker_apollonius(game: GameView) -> np.ndarray:
    cfg = game.config
    a, t, d = game.positions[:, ATTACKER], game.positions[:, TARGETER], game.positions[:, DEFENDER]
    home = unit(-t)
    rho, flight = home_path_meeting(game)
    first = np.minimum(rho, flight)
    fractions = np.linspace(0.0, 1.0, APPROACH_CANDIDATES)
    along = first[:, None] + fractions[None, :] * (flight - first)[:, None]  # (N, K), from P(rho) to P(S)
    path_home = t[:, None] + along[..., None] * home[:, None]  # (N, K, 3)
    lead = lead_intercept(a, cfg.v_attacker, t, heading_vectors(game.headings[:, TARGETER]) * cfg.v_targeter)
    aims = np.concatenate((lead[:, None], path_home), axis=1)  # (N, 1 + K, 3)
    steps = np.linspace(1.0 / PATH_POINTS, 1.0, PATH_POINTS)
    path = a[:, None, None] + steps[None, None, :, None] * (aims - a[:, None])[:, :, None]  # (N, K, P, 3)
    d_time = (norm(path - d[:, None, None]) - cfg.defender_radius) / cfg.v_defender
    a_time = norm(path - a[:, None, None]) / cfg.v_attacker
    open_approach = np.all(d_time > a_time, axis=2)  # (N, K)
    # The first open approach; with none open, P(min(rho, S)), the first of the path home.
    choice = np.where(open_approach.any(axis=1), np.argmax(open_approach, axis=1), 1)
    direction: np.ndarray = aims[np.arange(len(a)), choice] - a
    return direction


def defense_plane(game: GameView) -> tuple[np.ndarray, np.ndarray]:
    """``(M, n)`` ``(N, 3)`` each: a point of the A/D boundary plane and its unit normal toward A."""
    cfg = game.config
    a, d = game.positions[:, ATTACKER], game.positions[:, DEFENDER]
    d_reach = d + np.minimum(cfg.defender_radius, norm(a - d))[:, None] * unit(a - d)
    meeting = d_reach + cfg.v_defender / (cfg.v_defender + cfg.v_attacker) * (a - d_reach)
    return meeting, unit(a - d_reach)


def targeter_ball(game: GameView) -> tuple[np.ndarray, np.ndarray]:
    """Centre ``(N, 3)`` and radius ``(N,)`` of T's Apollonius ball against ``A_r``."""
    cfg = game.config
    a, t = game.positions[:, ATTACKER], game.positions[:, TARGETER]
    k2 = (cfg.v_targeter / cfg.v_attacker) ** 2
    a_reach = a + np.minimum(cfg.attacker_radius, norm(t - a))[:, None] * unit(t - a)
    centre = (t - k2 * a_reach) / (1.0 - k2)
    radius = np.sqrt(k2) * norm(t - a_reach) / (1.0 - k2)
    return centre, radius


def refuge_point(game: GameView) -> np.ndarray:
    """``c - R n`` ``(N, 3)``: the point of T's ball deepest into D's side of the plane (targeter step 2)."""
    centre, radius = targeter_ball(game)
    _, normal = defense_plane(game)
    deepest: np.ndarray = centre - radius[:, None] * normal
    return deepest


def targeter_active_defense(game: GameView) -> np.ndarray:
    a, t = game.positions[:, ATTACKER], game.positions[:, TARGETER]
    race = race_margin(game.positions, game.config) > 0
    attacker_velocity = heading_vectors(game.headings[:, ATTACKER])
    oncoming = dot(t - a, attacker_velocity) > 0
    direction: np.ndarray = np.where((race | ~oncoming)[:, None], -t, refuge_point(game) - t)
    return direction


def interception_point(game: GameView) -> tuple[np.ndarray, np.ndarray]:
    """``I*`` ``(N, 3)`` on the A/D plane, and whether T is on D's side of it ``(N,)``."""
    cfg = game.config
    a, t = game.positions[:, ATTACKER], game.positions[:, TARGETER]
    k = cfg.v_targeter / cfg.v_attacker
    meeting, normal = defense_plane(game)
    t_side, a_side = dot(t - meeting, normal), dot(a - meeting, normal)
    t_p, a_p = t - t_side[:, None] * normal, a - a_side[:, None] * normal
    segment = a_p - t_p
    low, high = np.zeros(len(t)), np.ones(len(t))
    for _ in range(BISECTIONS):
        middle = 0.5 * (low + high)
        point = t_p + middle[:, None] * segment
        slope = dot(segment, unit(point - t)) + k * dot(segment, unit(point - a))
        rising = slope > 0
        high, low = np.where(rising, middle, high), np.where(rising, low, middle)
    return t_p + (0.5 * (low + high))[:, None] * segment, t_side < 0


def defender_active_defense(game: GameView) -> np.ndarray:
    a, d = game.positions[:, ATTACKER], game.positions[:, DEFENDER]
    aim, in_front = interception_point(game)
    direction: np.ndarray = np.where(in_front[:, None], aim - d, a - d)
    return direction

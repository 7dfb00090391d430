"""Per-step rewards of ``shared/paper.md`` section 4.2, as pure functions over a batch.

``gamma_steps`` is the game's time limit ``Gamma`` in steps (one per game); the paper
divides every per-step reward by it so that an episode's return stays bounded.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

Method3Variant = Literal["as_printed", "corrected"]

# Eq. 7 and Eq. 9: the change in distance that counts as progress.
METHOD1_THRESHOLD = 0.1
METHOD3_THRESHOLD = 0.05


def attacker_method1(
    d_at_prev: np.ndarray, d_at: np.ndarray, d_ad_prev: np.ndarray, d_ad: np.ndarray, gamma_steps: np.ndarray
) -> np.ndarray:
    """Eq. 7: reward A for closing on T and not closing on D.

    ``dAT = |A_{t-1} T_{t-1}| - |A_t T_t|`` and ``dAD = |A_{t-1} D_{t-1}| - |A_t D_t|``.

    | dAT > 0.1 | dAD > 0.1 | reward    |
    | --------- | --------- | --------- |
    | yes       | no        | 45 / Gamma |
    | yes       | yes       | 30 / Gamma |
    | no        | no        | 3 / Gamma  |
    | no        | yes       | 0          |
    """
    closing_on_t = (d_at_prev - d_at) > METHOD1_THRESHOLD
    closing_on_d = (d_ad_prev - d_ad) > METHOD1_THRESHOLD
    reward = np.where(closing_on_t, np.where(closing_on_d, 30.0, 45.0), np.where(closing_on_d, 0.0, 3.0))
    paid: np.ndarray = reward / gamma_steps
    return paid


def attacker_method2(offset_angle: np.ndarray, sigma_a: float, gamma_steps: np.ndarray) -> np.ndarray:
    """Eq. 8: reward A for moving along its reference direction.

    ``offset_angle`` is ``d sigma_A``, the angle between A's "actual direction" and the
    reference direction (A to T's lead-intercept point, see the core). The paper does not
    say which direction is actual; ``method2_direction`` picks the chord of A's motion
    this step (default) or A's heading at the end of the step. They differ on a turn: the
    chord points halfway through it, so an attacker that turns exactly onto the reference
    direction is scored on half its turn by the chord and fully by the heading.
    With ``x = d sigma_A / sigma_a``:

    | case       | reward                        |
    | ---------- | ----------------------------- |
    | x <= 1     | max(2 - x, 1) * 30 / Gamma    |
    | 1 < x <= 2 | max(2 - x, 0) * 30 / Gamma    |
    | x > 2      | max(1 - x, -2) * 30 / Gamma   |
    """
    x = offset_angle / sigma_a
    score = np.where(x <= 1, np.maximum(2 - x, 1), np.where(x <= 2, np.maximum(2 - x, 0), np.maximum(1 - x, -2)))
    paid: np.ndarray = score * 30.0 / gamma_steps
    return paid


def attacker_method3(
    lambda_prev: np.ndarray,
    lambda_now: np.ndarray,
    overchase_count: np.ndarray,
    overchase_gamma: float,
    gamma_steps: np.ndarray,
    variant: Method3Variant = "as_printed",
) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 9: reward A for shrinking ``lambda``, its distance to the predicted collision point.

    With ``dl = lambda_t - lambda_{t-1}``:

    | case                            | reward                                                      |
    | ------------------------------- | ----------------------------------------------------------- |
    | lambda_{t-1} - lambda_t >= 0.05 | min(2 abs(dl) + 1, 2) * 10 / Gamma                          |
    | lambda_{t-1} - lambda_t <  0.05 | ``as_printed``: -max(-2 abs(dl), -1) * 10 / Gamma - gamma ** C |
    |                                 | ``corrected``: -(min(2 abs(dl), 1) + gamma ** C) * 10 / Gamma  |

    The second row is the over-chasing case: its counter ``C`` is incremented first, so
    the first such step costs ``gamma ** 1``. As printed, ``-max(-2|dl|, -1)`` is a
    *positive* term that grows with ``|dl|`` (over-chasing harder pays more), and
    ``gamma ** C`` alone is not divided by ``Gamma``: probably a sign slip and a missing
    scale. ``corrected`` makes the first term a cost and scales ``gamma ** C`` like the
    rest, by ``10 / Gamma``.

    Returns ``(reward, new_count)``.
    """
    change = np.abs(lambda_now - lambda_prev)
    progress = (lambda_prev - lambda_now) >= METHOD3_THRESHOLD
    new_count = np.where(progress, overchase_count, overchase_count + 1)
    gain = np.minimum(2 * change + 1, 2) * 10.0 / gamma_steps
    if variant == "as_printed":
        penalty = -np.maximum(-2 * change, -1) * 10.0 / gamma_steps - np.power(overchase_gamma, new_count)
    else:
        penalty = -(np.minimum(2 * change, 1) + np.power(overchase_gamma, new_count)) * 10.0 / gamma_steps
    return np.where(progress, gain, penalty), new_count


def team_rewards(
    d_tter: np.ndarray, d_at: np.ndarray, d_da: np.ndarray, w_t1: float, w_t2: float, gamma_steps: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 10 and 11 with the sign fixed: ``(r_T, r_D)``.

    The paper writes the *costs* ``J_T = w_T1 d_Tter - w_T2 d_AT`` and ``J_D = d_DA``
    that T and D minimise, then reuses them unchanged as rewards, which would pay T
    for staying away from the terminal. We reward the negated costs:
    ``r_T = -(w_T1 d_Tter - w_T2 d_AT) / Gamma`` and ``r_D = -d_DA / Gamma``.
    """
    r_t = -(w_t1 * d_tter - w_t2 * d_at) / gamma_steps
    r_d = -d_da / gamma_steps
    return r_t, r_d

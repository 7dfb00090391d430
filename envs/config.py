"""Game parameters: one validated object shared by the core, the adapters and the league.

Defaults follow ``shared/paper.md`` section 5 as read by ``shared/design.md`` section 1.
Unknown keys, wrong types, infinite or NaN floats and impossible values raise
``pydantic.ValidationError`` naming the key.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, PositiveFloat, model_validator

from envs.rewards import Method3Variant

ObservationMode = Literal["paper", "rich"]
ActionMode = Literal["relative", "absolute"]
Method2Direction = Literal["chord", "heading"]


class GameConfig(BaseModel):
    """Everything that defines one game of 3D cooperative target defense."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, use_attribute_docstrings=True)

    v_attacker: PositiveFloat = 0.18
    """Distance A moves per step."""
    v_targeter: PositiveFloat = 0.13
    """Distance T moves per step; must stay below ``v_attacker``."""
    v_defender: PositiveFloat = 0.18
    """Distance D moves per step."""
    max_yaw_change: float = Field(math.pi / 2, gt=0, le=math.pi)
    """Largest yaw change per step (radians)."""
    max_pitch_change: float = Field(math.pi / 4, gt=0, le=math.pi / 2)
    """Largest pitch change per step (radians)."""
    axis_length: float = Field(0.1, ge=0)
    """``L``: the turn radius never goes below it, so a heading turns at most ``v / L`` per step,
    measured as the true angle between the old and the new heading after the pitch clamp
    (``envs.kinematics``). ``0`` leaves ``L`` out: the explicit yaw and pitch limits alone."""
    attacker_capture_radius: PositiveFloat | None = None
    """A captures T within this distance; ``None`` means ``v_attacker`` (the paper's)."""
    defender_capture_radius: PositiveFloat | None = None
    """D captures A within this distance; ``None`` means ``v_defender``."""
    terminal_radius: PositiveFloat | None = None
    """T reaches the terminal within this distance; ``None`` means ``v_targeter``."""
    time_limit_factor: PositiveFloat = 2.0
    """``Gamma = ceil(time_limit_factor * |T0 - ter| / v_targeter)`` steps, the ceiling taken
    with a tolerance of 1e-9 relative so float rounding of an exact multiple adds no step."""
    attacker_reward: Literal[1, 2, 3] = 2
    """Which of the paper's attacker reward methods (Eq. 7, 8, 9) the attacker receives."""
    sigma_a: float = Field(math.pi / 6, gt=0, lt=math.pi)
    """Acceptable angular offset of method 2 (radians); the paper gives no value."""
    method2_direction: Method2Direction = "chord"
    """A's "actual direction" in Eq. 8: ``chord`` of its motion this step (default; the
    direction it really moved), or its ``heading`` at the end of the step (what it chose)."""
    overchase_gamma: float = Field(1.08, gt=0)
    """Base of the over-chasing penalty ``gamma ** C`` in method 3."""
    method3_variant: Method3Variant = "as_printed"
    """Eq. 9 ``as_printed`` (default: a positive first term in the over-chasing case,
    ``gamma ** C`` not divided by Gamma), or ``corrected`` (both a cost scaled by 10 / Gamma);
    see ``envs.rewards.attacker_method3``."""
    w_t1: PositiveFloat = 0.6
    """Weight of T's distance to the terminal in Eq. 10."""
    w_t2: PositiveFloat = 0.4
    """Weight of the A-T distance in Eq. 10."""
    terminal_reward: float = Field(0.0, ge=0)
    """Win (+) / loss (-) reward added on the last step; 0 in the paper."""
    observation: ObservationMode = "rich"
    """``paper``: the paper's 15 numbers (plus the role for T and D); ``rich``: agent-centred."""
    action_mode: ActionMode = "relative"
    """``relative``: turn in [-1, 1] scaled to the limits; ``absolute``: the paper's heading."""
    scenario: str = "default"
    """Name of the scenario set that draws the starting positions (``envs.scenarios``)."""
    position_scale: PositiveFloat = 4.0
    """Length that divides positions and distances in the ``rich`` observation."""
    attacker_memory: bool = False
    """A's observation ends with one more number: the largest turn T has made away from its line
    home so far in the game, as a fraction of T's largest turn per step (``envs.observations``).
    A T that flies straight home never turns away; one that hides from an oncoming A does."""

    @model_validator(mode="after")
    def _check_game(self) -> "GameConfig":
        if self.v_attacker <= self.v_targeter:
            raise ValueError(
                f"v_attacker ({self.v_attacker}) must be greater than v_targeter "
                f"({self.v_targeter}): the attacker could never catch the targeter"
            )
        from envs.scenarios import SCENARIO_SETS  # late import: scenarios reads the config

        if self.scenario not in SCENARIO_SETS:
            raise ValueError(f"scenario {self.scenario!r} is not one of {sorted(SCENARIO_SETS)}")
        return self

    @property
    def speeds(self) -> tuple[float, float, float]:
        """Per-step distances in agent order (attacker, targeter, defender)."""
        return (self.v_attacker, self.v_targeter, self.v_defender)

    @property
    def attacker_radius(self) -> float:
        return self.attacker_capture_radius or self.v_attacker

    @property
    def defender_radius(self) -> float:
        return self.defender_capture_radius or self.v_defender

    @property
    def terminal_sphere_radius(self) -> float:
        return self.terminal_radius or self.v_targeter

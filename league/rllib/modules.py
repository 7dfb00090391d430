"""The RLModules of the league: learned actor-critics and scripted players.

Every agent's observation arrives with the env's 22-number global state appended
(``envs.rllib_env``, ``with_global_state``): ``obs = [own observation | global state]``.

* ``ActorCriticModule``: a Gaussian policy over the own observation only, and a value
  network over either the global state and the agent's role (``critic: global``, the
  team's MAPPO critic) or the own observation (``critic: local``, plain PPO, the
  attacker's). The role matters: T and D are paid differently (Eq. 10 vs 11), so at one
  global state their values differ, and a critic blind to the role can only learn their
  average, which biases both agents' advantages.
  With ``prior: lead_intercept`` or ``apollonius`` (``PPOSettings.attacker_prior``) the actor is a
  ``ResidualActor``: that scripted attacker's turn plus the network's output; with a scripted team as
  ``prior`` (``PPOSettings.team_prior``), that team's turn for T or D plus the network's
  output (``ScriptedTeamTurn``). With
  ``heading_cosines`` (``PPOSettings.attacker_heading_cosines``) the actor's network reads
  two numbers more, ``HeadingCosines``; with ``scripted_turns`` four more, ``ScriptedTurns``.
* ``ScriptedModule``: a scripted player of ``envs.scripted``, reading the global state;
  it returns actions directly and is never trained.
"""

from __future__ import annotations

import logging
from functools import partial
from typing import Any

import numpy as np
import torch
from torch import nn

from envs.config import GameConfig
from envs.observations import (
    RICH_FIRST_OTHER,
    RICH_HEADING,
    RICH_SECOND_OTHER,
    RICH_TERMINAL,
    ROLE_SIZE,
    role_of,
    split_policy_input,
)
from envs.scripted import SHELTER_DISTANCE, act_from_state
from envs.theory_players import APPROACH_CANDIDATES, PATH_POINTS
from league.rllib.module_settings import ActorCriticSettings, ScriptedSettings
from ray.rllib.core.columns import Columns
from ray.rllib.core.rl_module.apis.value_function_api import ValueFunctionAPI
from ray.rllib.core.rl_module.torch import TorchRLModule

# Initial log standard deviation of the Gaussian policy (std ~0.6 of the [-1, 1] range).
INITIAL_LOG_STD = -0.5
# A's memory above which T has turned away from home (a fraction of T's largest turn per step):
# a straight-flying T stays below 1e-6, most avoiding T that lead intercept comes at pass 0.05.
TARGETER_TURNED = 0.05


class _RLModuleConfigNotice(logging.Filter):
    """Drops Ray 2.60's ``RLModule(config=RLModuleConfig)`` DeprecationWarning.

    Our modules are built the current way (``RLModuleSpec`` with ``model_config``, i.e.
    ``RLModule(observation_space=..., action_space=..., model_config=...)``), but
    ``RLModule.__init__`` itself still builds an ``RLModuleConfig`` for old subclasses, and
    that deprecated class warns on every first construction in a process, whoever calls it.
    """

    def filter(self, record: logging.LogRecord) -> bool:
        return "RLModuleConfig" not in record.getMessage()


logging.getLogger("ray._common.deprecation").addFilter(_RLModuleConfigNotice())


def mlp(inputs: int, hidden: list[int], outputs: int, last_gain: float, features: nn.Module | None = None) -> nn.Sequential:
    """Tanh layers of ``hidden`` sizes and a linear head; ``features``, if given, first adds
    ``features.size`` numbers to the ``inputs``."""
    layers: list[nn.Module] = []
    if features is not None:
        layers.append(features)
        inputs += features.size
    for size in hidden:
        linear = nn.Linear(inputs, size)
        nn.init.orthogonal_(linear.weight, gain=np.sqrt(2))
        nn.init.zeros_(linear.bias)
        layers += [linear, nn.Tanh()]
        inputs = size
    head = nn.Linear(inputs, outputs)
    nn.init.orthogonal_(head.weight, gain=last_gain)
    nn.init.zeros_(head.bias)
    return nn.Sequential(*layers, head)


def turn_toward(aim: torch.Tensor, own: torch.Tensor, max_yaw_change: float, max_pitch_change: float) -> torch.Tensor:
    """The relative action that turns toward ``aim`` (a vector in the agent's yaw frame, from its
    ``rich`` observation ``own``) as far as the limits allow: ``envs.scripted.direction_to_action``.
    In that frame the agent's yaw is 0, so the yaw to turn is the aim's azimuth."""
    pitch = torch.atan2(own[..., 0], own[..., 1])
    yaw_turn = torch.atan2(aim[..., 1], aim[..., 0])
    pitch_turn = torch.atan2(aim[..., 2], torch.sqrt(aim[..., 0] ** 2 + aim[..., 1] ** 2)) - pitch
    return torch.stack((yaw_turn / max_yaw_change, pitch_turn / max_pitch_change), dim=-1).clamp(-1.0, 1.0)


def lead_point(r: torch.Tensor, u: torch.Tensor, speed: float) -> torch.Tensor:
    """Where a chaser at ``speed`` meets a target at ``r`` from it moving at velocity ``u``
    (``envs.geometry.lead_intercept``: the positive root of ``|r + u s| = speed s``), relative to the chaser."""
    ru = (r * u).sum(-1)
    margin = speed**2 - (u * u).sum(-1)
    meeting = (ru + torch.sqrt(ru * ru + margin * (r * r).sum(-1))) / margin
    return r + u * meeting.unsqueeze(-1)


class LeadInterceptTurn(nn.Module):
    """Lead intercept's action (``envs.scripted``: fly at the point where T, at its current
    velocity, is met) from the attacker's ``rich`` observation alone: T's position relative to
    A and T's heading, both in A's yaw frame, and A's pitch."""

    def __init__(self, game: GameConfig):
        super().__init__()
        # Lengths in the observation are divided by position_scale; so are the speeds here.
        self.v_attacker = game.v_attacker / game.position_scale
        self.v_targeter = game.v_targeter / game.position_scale
        self.max_yaw_change = game.max_yaw_change
        self.max_pitch_change = game.max_pitch_change
        self.t = RICH_FIRST_OTHER  # the attacker sees T first (envs.observations)
        self.t_heading = RICH_FIRST_OTHER + RICH_HEADING

    def forward(self, own: torch.Tensor) -> torch.Tensor:
        own = own.float()
        r = own[..., self.t : self.t + 3]  # T - A
        u = own[..., self.t_heading : self.t_heading + 3] * self.v_targeter  # T's velocity
        return turn_toward(lead_point(r, u, self.v_attacker), own, self.max_yaw_change, self.max_pitch_change)


class ApolloniusTurn(nn.Module):
    """The Apollonius attacker's action (``envs.theory_players.attacker_apollonius``: T's earliest
    interception point, else the first point of T's straight path home from the edge of its
    Apollonius region that D does not cut off) from the attacker's ``rich`` observation alone:
    T, D and the terminal relative to A, T's heading, all in A's yaw frame, and A's pitch."""

    def __init__(self, game: GameConfig):
        super().__init__()
        scale = game.position_scale  # lengths in the observation are divided by it; so are the speeds here
        self.v_attacker, self.v_targeter, self.v_defender = game.v_attacker / scale, game.v_targeter / scale, game.v_defender / scale
        self.capture_radius, self.defender_radius = game.attacker_radius / scale, game.defender_radius / scale
        self.terminal_radius = game.terminal_sphere_radius / scale
        self.max_yaw_change, self.max_pitch_change = game.max_yaw_change, game.max_pitch_change
        # Block starts as attributes: TorchScript does not read module-level ints in forward.
        self.t, self.d, self.terminal, self.heading = RICH_FIRST_OTHER, RICH_SECOND_OTHER, RICH_TERMINAL, RICH_HEADING
        self.register_buffer("along", torch.linspace(0.0, 1.0, APPROACH_CANDIDATES), persistent=False)
        self.register_buffer("steps", torch.linspace(1.0 / PATH_POINTS, 1.0, PATH_POINTS), persistent=False)

    def forward(self, own: torch.Tensor) -> torch.Tensor:
        own = own.float()
        t, d = own[..., self.t : self.t + 3], own[..., self.d : self.d + 3]  # T - A, D - A
        to_terminal = own[..., self.terminal : self.terminal + 3] - t  # terminal - T
        u = own[..., self.t + self.heading : self.t + self.heading + 3] * self.v_targeter  # T's velocity
        distance_home = torch.linalg.vector_norm(to_terminal, dim=-1)
        home = to_terminal / distance_home.clamp_min(1e-12).unsqueeze(-1)
        # envs.start_classes.region_radius with A at the origin: where T's path home leaves its region.
        k = self.v_targeter / self.v_attacker
        r = self.capture_radius
        qa = 1.0 / (k * k) - 1.0
        qb = 2.0 * (r / k - (t * home).sum(-1))
        qc = r * r - (t * t).sum(-1)
        rho = (-qb + torch.sqrt((qb * qb - 4.0 * qa * qc).clamp_min(0.0))) / (2.0 * qa)
        rho = torch.where(qc < 0, rho, torch.zeros_like(rho))
        flight = (distance_home - self.terminal_radius).clamp_min(0.0)
        first = torch.minimum(rho, flight)
        distances = first.unsqueeze(-1) + self.along * (flight - first).unsqueeze(-1)  # (..., K)
        path_home = t.unsqueeze(-2) + distances.unsqueeze(-1) * home.unsqueeze(-2)  # (..., K, 3)
        aims = torch.cat((lead_point(t, u, self.v_attacker).unsqueeze(-2), path_home), dim=-2)  # (..., 1 + K, 3)
        path = self.steps.unsqueeze(-1) * aims.unsqueeze(-2)  # (..., 1 + K, P, 3): A's straight approach
        d_time = (torch.linalg.vector_norm(path - d.unsqueeze(-2).unsqueeze(-2), dim=-1) - self.defender_radius) / self.v_defender
        a_time = torch.linalg.vector_norm(path, dim=-1) / self.v_attacker
        open_approach = (d_time > a_time).all(dim=-1)  # (..., 1 + K)
        # The first open approach; with none open, the first point of the path home.
        first_open = torch.argmax(open_approach.to(torch.int32), dim=-1)
        choice = torch.where(open_approach.any(dim=-1), first_open, torch.ones_like(first_open))
        aim = torch.gather(aims, -2, choice.unsqueeze(-1).unsqueeze(-1).expand(choice.shape + (1, 3))).squeeze(-2)
        return turn_toward(aim, own, self.max_yaw_change, self.max_pitch_change)


class ScriptedTurns(nn.Module):
    """The attacker's ``rich`` observation with four numbers appended: lead intercept's turn and the
    Apollonius attacker's (``LeadInterceptTurn``, ``ApolloniusTurn``), the two attackers that are best
    against the scripted teams whose D intercepts and whose D chases A."""

    size = 4

    def __init__(self, game: GameConfig):
        super().__init__()
        self.lead, self.apollonius = LeadInterceptTurn(game), ApolloniusTurn(game)

    def forward(self, own: torch.Tensor) -> torch.Tensor:
        return torch.cat((own, self.lead(own), self.apollonius(own)), dim=-1)


class ScriptedTeamTurn(nn.Module):
    """A scripted team's action from T's or D's ``rich`` observation (the role one-hot that ends
    it says which): D turns toward A (``pure_pursuit``); T toward the terminal (``straight``),
    or only while it is safe (``avoid_attacker``: ``envs.scripted.targeter_is_safe``, it
    reaches the terminal sphere before A can come within its capture radius), else toward a
    point behind D as seen from A; ``avoid_oncoming_attacker`` hides only while A flies toward T."""

    targeters = ("straight", "avoid_attacker", "avoid_oncoming_attacker")

    def __init__(self, game: GameConfig, targeter: str):
        super().__init__()
        if targeter not in self.targeters:
            raise ValueError(f"no team prior for the targeter {targeter!r}; expected one of {self.targeters}")
        self.avoid = targeter != "straight"
        self.oncoming_only = targeter == "avoid_oncoming_attacker"
        scale = game.position_scale  # lengths in the observation are divided by it
        self.v_targeter, self.v_attacker = game.v_targeter / scale, game.v_attacker / scale
        self.capture_radius, self.terminal_radius = game.attacker_radius / scale, game.terminal_sphere_radius / scale
        self.shelter_distance = SHELTER_DISTANCE / scale
        self.max_yaw_change, self.max_pitch_change = game.max_yaw_change, game.max_pitch_change
        # Block starts as attributes: TorchScript does not read module-level ints in forward.
        self.a, self.d, self.terminal, self.targeter_flag = RICH_FIRST_OTHER, RICH_SECOND_OTHER, RICH_TERMINAL, -ROLE_SIZE
        self.heading = RICH_HEADING

    def forward(self, own: torch.Tensor) -> torch.Tensor:
        own = own.float()
        a, d = own[..., self.a : self.a + 3], own[..., self.d : self.d + 3]  # T's view: A first, then D
        e = own[..., self.terminal : self.terminal + 3]  # the terminal, relative to T
        targeter_aim = e
        if self.avoid:
            to_terminal = torch.linalg.vector_norm(e, dim=-1)
            goal = e * (1 - self.terminal_radius / to_terminal.clamp_min(self.terminal_radius)).unsqueeze(-1)
            margin = (self.v_targeter * (torch.linalg.vector_norm(goal - a, dim=-1) - self.capture_radius)
                      - self.v_attacker * torch.linalg.vector_norm(goal, dim=-1))
            home = (to_terminal <= self.terminal_radius) | (margin > 0)  # safe
            if self.oncoming_only:  # or A is not flying toward T (A's heading is in T's frame, as A's position)
                a_heading = own[..., self.a + self.heading : self.a + self.heading + 3]
                home = home | ((-a * a_heading).sum(-1) <= 0)
            away = d - a
            shelter = d + self.shelter_distance * away / torch.linalg.vector_norm(away, dim=-1, keepdim=True).clamp_min(1e-12)
            targeter_aim = torch.where(home.unsqueeze(-1), e, shelter)
        targeter = own[..., self.targeter_flag].unsqueeze(-1) > 0.5  # the role one-hot (targeter, defender)
        aim = torch.where(targeter, targeter_aim, a)  # D sees A first too
        return turn_toward(aim, own, self.max_yaw_change, self.max_pitch_change)


class HeadingCosines(nn.Module):
    """The attacker's ``rich`` observation with two numbers appended: the cosine between T's
    heading and T's line to the terminal, and between D's heading and D's line to A. They tell
    the scripted teams apart (a straight-flying T's is 1, a pursuing D's is 1); the observation
    holds them already, but only as quotients of its numbers (docs/results/selfplay-league.md)."""

    size = 2

    def __init__(self):
        super().__init__()
        # Block starts as attributes: TorchScript does not read module-level ints in forward.
        self.t, self.d, self.terminal, self.heading = RICH_FIRST_OTHER, RICH_SECOND_OTHER, RICH_TERMINAL, RICH_HEADING

    def forward(self, own: torch.Tensor) -> torch.Tensor:
        t, d, h = self.t, self.d, self.heading  # the attacker sees T first, then D, in its yaw frame
        a_to_t, t_heading = own[..., t : t + 3], own[..., t + h : t + h + 3]
        a_to_d, d_heading = own[..., d : d + 3], own[..., d + h : d + h + 3]
        t_to_terminal = own[..., self.terminal : self.terminal + 3] - a_to_t  # (terminal - A) - (T - A)
        cos_t = (t_heading * t_to_terminal).sum(-1) / torch.linalg.vector_norm(t_to_terminal, dim=-1).clamp_min(1e-6)
        cos_d = -(d_heading * a_to_d).sum(-1) / torch.linalg.vector_norm(a_to_d, dim=-1).clamp_min(1e-6)
        return torch.cat((own, torch.stack((cos_t, cos_d), dim=-1)), dim=-1)


class ResidualActor(nn.Module):
    """A scripted player's action plus a network's: the network learns the correction."""

    def __init__(self, prior: nn.Module, net: nn.Module):
        super().__init__()
        self.prior, self.net = prior, net

    def forward(self, own: torch.Tensor) -> torch.Tensor:
        return self.prior(own) + self.net(own)


# Named as in the config: ``ppo.attacker_prior``, ``ppo.team_prior``.
PRIORS = {
    "lead_intercept": LeadInterceptTurn,
    "apollonius": ApolloniusTurn,
    **{f"{targeter}+pure_pursuit": partial(ScriptedTeamTurn, targeter=targeter) for targeter in ScriptedTeamTurn.targeters},
}


class AppendedFeatures(nn.Sequential):
    """Feature modules one after the other; each appends its numbers to the observation's end, so the
    blocks that the next one reads stay in place."""

    def __init__(self, *parts: nn.Module):
        super().__init__(*parts)
        self.size = sum(part.size for part in parts)


def appended_features(settings: ActorCriticSettings) -> nn.Module | None:
    """The numbers the actor's network reads after the observation, or ``None``."""
    parts: list[nn.Module] = []
    if settings.heading_cosines:
        parts.append(HeadingCosines())
    if settings.scripted_turns:
        parts.append(ScriptedTurns(settings.game))
    if len(parts) > 1:
        return AppendedFeatures(*parts)
    return parts[0] if parts else None  # one module alone, as before there were two


class ActorCriticModule(TorchRLModule, ValueFunctionAPI):
    """PPO actor-critic built as its ``settings`` say (``ActorCriticSettings``, from ``model_config``)."""

    def setup(self) -> None:
        self.settings = settings = ActorCriticSettings.from_model_config(self.model_config)
        self.actor_inputs = settings.actor_inputs
        self.critic_input = settings.critic
        total = self.observation_space.shape[0]
        critic_inputs = total - self.actor_inputs + ROLE_SIZE if self.critic_input == "global" else self.actor_inputs
        actions = self.action_space.shape[0]
        hidden = list(settings.hidden)
        features = appended_features(settings)
        self.pi = mlp(self.actor_inputs, hidden, actions, last_gain=0.01, features=features)
        if settings.prior != "none":
            self.pi = ResidualActor(PRIORS[settings.prior](settings.game), self.pi)
        self.log_std = nn.Parameter(torch.full((actions,), INITIAL_LOG_STD))
        self.vf = mlp(critic_inputs, hidden, 1, last_gain=1.0)

    def actor_features(self, obs: torch.Tensor) -> torch.Tensor:
        return split_policy_input(obs, self.actor_inputs)[0]

    def critic_features(self, obs: torch.Tensor) -> torch.Tensor:
        own, state = split_policy_input(obs, self.actor_inputs)
        return torch.cat((state, role_of(own)), dim=-1) if self.critic_input == "global" else own

    def deterministic_action(self, obs: torch.Tensor) -> torch.Tensor:
        """The Gaussian's mean: what the policy does when not exploring."""
        return self.pi(self.actor_features(obs))

    def prior_correction(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``action_dist_inputs`` and the network's part of the mean, what it adds to the prior's turn
        (``ResidualActor``), from one pass of the network."""
        if not isinstance(self.pi, ResidualActor):
            raise ValueError("a module without a prior has no correction of one")
        own = self.actor_features(obs)
        correction = self.pi.net(own)
        return self.dist_inputs(self.pi.prior(own) + correction), correction

    def targeter_still_straight(self, obs: torch.Tensor) -> torch.Tensor:
        """1.0 on rows where A's memory (the last number of its observation) says T has not turned away, else 0.0."""
        if not self.settings.game.attacker_memory:
            raise ValueError("without game.attacker_memory the attacker remembers no turn of T")
        return (self.actor_features(obs)[..., -1] < TARGETER_TURNED).float()

    def action_dist_inputs(self, obs: torch.Tensor) -> torch.Tensor:
        """The Gaussian's mean and log standard deviation, side by side (RLlib's ``TorchDiagGaussian`` inputs)."""
        return self.dist_inputs(self.deterministic_action(obs))

    def dist_inputs(self, mean: torch.Tensor) -> torch.Tensor:
        return torch.cat((mean, self.log_std.expand_as(mean)), dim=-1)

    def _forward(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        return {Columns.ACTION_DIST_INPUTS: self.action_dist_inputs(batch[Columns.OBS])}

    def compute_values(self, batch: dict[str, Any], embeddings: Any = None) -> torch.Tensor:
        return self.vf(self.critic_features(batch[Columns.OBS])).squeeze(-1)


class ScriptedModule(TorchRLModule):
    """A scripted player, the one its ``settings`` name (``ScriptedSettings``, from ``model_config``)."""

    def setup(self) -> None:
        self.settings = settings = ScriptedSettings.from_model_config(self.model_config)
        self.game_config, self.agent, self.name = settings.game, settings.agent, settings.name
        self.actor_inputs = settings.actor_inputs

    def _forward(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        obs = batch[Columns.OBS]
        states = split_policy_input(obs, self.actor_inputs)[1].detach().cpu().numpy()
        actions = act_from_state(self.game_config, self.agent, self.name, states)
        return {Columns.ACTIONS: torch.as_tensor(actions, dtype=torch.float32)}

    def _forward_train(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        raise RuntimeError(f"scripted module {self.agent}/{self.name} is never trained: keep it out of policies_to_train")

"""Run configuration: YAML files in ``configs/`` validated by these pydantic models.

Every model forbids unknown keys, so a typo stops the run with the key's name, and
rejects infinite and NaN floats. ``load_config`` (a config file) and ``saved_run_config``
(the copy a run keeps) turn any problem (missing file, bad YAML, invalid value) into a
``ConfigError`` whose message names the file and the key; the CLIs print it and exit
with code 2 before anything is written.
"""

from __future__ import annotations

import difflib
import hashlib
import json
from pathlib import Path
import types
from typing import Annotated, Any, Literal, Union, get_args, get_origin

import yaml
from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError, ValidationInfo, field_validator, model_validator

from envs.config import GameConfig
from envs.scripted import PAPER_TEAM, PLAYERS

# Run configs by name: inside the package when installed from a wheel (pyproject.toml ships
# configs/ as league/configs), else beside it (a source checkout, an editable install).
_PACKAGE_DIR = Path(__file__).resolve().parent
CONFIG_DIR = _PACKAGE_DIR / "configs" if (_PACKAGE_DIR / "configs").is_dir() else _PACKAGE_DIR.parent / "configs"
RUN_CONFIG_FILE = "config.yaml"  # the validated config a run keeps in its directory
Side = Literal["attacker", "team"]


class ConfigError(ValueError):
    """A run configuration that cannot be used; the message says where and why."""


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, use_attribute_docstrings=True)


class PPOSettings(Strict):
    """PPO hyperparameters, shared by the attacker and the team learner."""

    lr: float = Field(3e-4, gt=0)
    """Adam's learning rate (both learners)."""
    lr_schedule: list[tuple[Annotated[int, Field(ge=0)], Annotated[float, Field(gt=0)]]] | None = None
    """``[[env_steps, lr], ...]``, from 0 in increasing env steps: the learning rate interpolated
    linearly over the run's sampled env steps (RLlib's schedule), in place of ``lr``."""
    gamma: float = Field(0.99, gt=0, le=1)
    """Discount factor (the attacker's, and the team's unless ``team_gamma`` is set)."""
    lambda_: float = Field(0.95, ge=0, le=1)
    """GAE ``lambda`` (the attacker's, and the team's unless ``team_lambda_`` is set)."""
    team_gamma: float | None = Field(None, gt=0, le=1)
    """Discount of the team learner (T and D); ``None``: ``gamma``. Why the team needs a longer horizon:
    [learning.md](results/learning.md#the-teams-learning). Needs ``resources.sampler: fast``."""
    team_lambda_: float | None = Field(None, ge=0, le=1)
    """GAE ``lambda`` of the team learner; ``None``: ``lambda_``. Needs ``resources.sampler: fast``."""
    targeter_shaping: float = Field(0.0, ge=0)
    """``k`` of T's potential-based shaping of its training rewards, ``Phi = -k |T ter|``; 0: none. Without it T did not
    find the terminal ([learning.md](results/learning.md#the-teams-learning)). Needs ``resources.sampler: fast``."""
    defender_shaping: float = Field(0.0, ge=0)
    """``k`` of D's potential-based shaping of its training rewards, ``Phi = -k |D A|``, as ``targeter_shaping``; 0:
    none. Needs ``resources.sampler: fast``."""
    attacker_win_reward: float = Field(0.0, ge=0)
    """Added to the attacker's training reward on a game's last step, ``+`` on a win, ``-`` on a loss, on top of
    ``game.terminal_reward``; 0: none. Needs ``resources.sampler: fast``. Without it the method-2 attacker flew about as
    lead intercept does (``git show 2d1e270^:docs/results/flagship.md``, "How the settings were chosen")."""
    attacker_win_reward_methods: list[Literal[1, 2, 3]] | None = None
    """The reward methods whose attackers get ``attacker_win_reward``; default: every method.
    A league of several methods (``league.attacker_reward_methods``) may pay it to some only."""
    team_reward: Literal["own", "shared"] = "own"
    """What T and D learn from: ``own``, each its own reward (Eq. 10, 11); ``shared``, each the team's, the sum of both
    per step, so D is paid for the steps of T its interception saves. Needs ``resources.sampler: fast``."""
    clip_param: float = Field(0.2, gt=0)
    """PPO's clip range of the probability ratio."""
    entropy_coeff: float = Field(0.0, ge=0)
    """Weight of the policy's entropy bonus in the loss."""
    vf_loss_coeff: float = Field(0.5, ge=0)
    """Weight of the value loss in the loss."""
    grad_clip: float | None = Field(0.5, gt=0)
    """Global gradient norm clip of each update; ``None``: no clipping."""
    train_batch_size: int = Field(4000, ge=32, description="env steps per training iteration")
    minibatch_size: int = Field(500, ge=8)
    """Rows (or env steps, ``minibatch_counts``) per gradient step."""
    minibatch_counts: Literal["rows", "env_steps"] = "rows"
    """What ``minibatch_size`` counts: ``rows``; or ``env_steps``, the rows of that many env steps, so the team (two
    rows per env step) takes as many gradient steps as the attacker. Needs ``resources.sampler: fast``."""
    num_epochs: int = Field(5, ge=1)
    """Passes over each training batch (the attacker's, and the team's unless ``team_num_epochs`` is set)."""
    team_num_epochs: int | None = Field(None, ge=1)
    """Passes over each of the team's training batches, whose T and D rows make them twice the attacker's; ``None``:
    ``num_epochs``. Needs ``resources.sampler: fast``. What it pays: [league-time.md](results/league-time.md)."""
    hidden: list[Annotated[int, Field(ge=1)]] = Field(default_factory=lambda: [64, 64], min_length=1)
    """Hidden layer sizes of both the policy and the value network (the attacker's, and the
    team's unless ``team_hidden`` is set)."""
    team_hidden: list[Annotated[int, Field(ge=1)]] | None = Field(None, min_length=1)
    """Hidden layer sizes of the team's policy and value networks; ``None``: ``hidden``. What ``[256, 256]`` bought, at
    what cost: [learning.md](results/learning.md)."""
    attacker_prior: Literal["none", "lead_intercept", "apollonius"] = "none"
    """``lead_intercept``: the policy mean is lead intercept's turn plus the network's output, so the untrained attacker
    plays lead intercept; ``apollonius``: the same with the Apollonius attacker's turn; ``none``: the network's.
    Needs ``game.observation: rich``, ``game.action_mode: relative``."""
    team_prior: Literal["none", "straight+pure_pursuit", "avoid_attacker+pure_pursuit",
                        "avoid_oncoming_attacker+pure_pursuit"] = "none"
    """A scripted team (``envs.scripted``) whose turn plus the team's network output is its policy mean, so untrained it
    plays that team ([training.md](training.md)); ``none``: the network alone. Needs as ``attacker_prior`` does."""
    attacker_residual_penalty: float = Field(0.0, ge=0)
    """Weight of the attacker network's squared output (its correction of ``attacker_prior``'s turn, summed over the
    action's two numbers, averaged over the minibatch) in the attacker's loss, so the attacker leaves the prior only
    where that pays; 0: none. Needs ``attacker_prior`` and ``resources.sampler: fast``."""
    attacker_residual_penalty_gate: Literal["always", "until_targeter_turns"] = "always"
    """Where ``attacker_residual_penalty`` weighs: on every step, or only on steps where A's memory
    (``game.attacker_memory``) says T has not yet turned away from home (below ``TARGETER_TURNED``,
    ``league.rllib.modules``): A is pulled back to lead intercept against a T that flies straight home and is
    free against one that has hidden. ``until_targeter_turns`` needs ``game.attacker_memory``."""
    attacker_heading_cosines: bool = False
    """The attacker's network also reads two cosines of its observation: T's heading against T's line to the terminal,
    D's against D's line to A (``league.rllib.modules.HeadingCosines``). Needs ``game.observation: rich``."""
    attacker_scripted_turns: bool = False
    """The attacker's network also reads lead intercept's and the Apollonius attacker's turns, four numbers computed
    from its observation (``league.rllib.modules.ScriptedTurns``). Needs ``game.observation: rich``."""
    bf16: bool = False
    """The learner's forward and backward passes in bfloat16 where the CPU has it natively, else float32; it pays at
    wide networks only ([performance.md](performance.md)). Needs ``resources.sampler: fast``."""
    compile_loss: bool = False
    """The learner's loss, forward and backward, under ``torch.compile`` where torch finds the C++ compiler it builds
    kernels with, else eager; each trained module's first update compiles (seconds). What it pays:
    [performance.md](performance.md). Needs ``resources.sampler: fast``."""

    def minibatch(self, side: Side) -> int:
        """Rows per minibatch of the ``side`` learner's updates."""
        rows_per_env_step = 2 if side == "team" and self.minibatch_counts == "env_steps" else 1  # the team: T and D
        return rows_per_env_step * self.minibatch_size

    def epochs(self, side: Side) -> int:
        """Passes over each of the ``side`` learner's training batches."""
        return self.team_num_epochs if side == "team" and self.team_num_epochs is not None else self.num_epochs

    def hidden_of(self, side: Side) -> list[int]:
        """Hidden layer sizes of the ``side`` learner's networks."""
        return self.team_hidden if side == "team" and self.team_hidden is not None else self.hidden

    def win_reward(self, reward_method: int) -> float:
        """``attacker_win_reward`` of an attacker of ``reward_method``."""
        methods = self.attacker_win_reward_methods
        return self.attacker_win_reward if methods is None or reward_method in methods else 0.0

    def discount(self, side: Side) -> tuple[float, float]:
        """``(gamma, lambda)`` of the ``side`` learner."""
        if side == "team":
            return (
                self.gamma if self.team_gamma is None else self.team_gamma,
                self.lambda_ if self.team_lambda_ is None else self.team_lambda_,
            )
        return self.gamma, self.lambda_


class Resources(Strict):
    """Where sampling runs; ``num_cpus`` is used only when this run starts Ray itself
    (with ``--address`` the cluster's nodes bring their own)."""

    num_cpus: int = Field(2, ge=1)
    """CPUs of the Ray instance this run starts (not used with ``--address``)."""
    num_env_runners: int = Field(0, ge=0)
    """Remote env runners (Ray actors) that sample; 0: sample in the driver."""
    num_envs_per_env_runner: int = Field(8, ge=1)
    """Games each env runner steps at once."""
    num_cpus_per_env_runner: float = Field(1, gt=0)
    """CPUs Ray reserves for each remote env runner."""
    custom_resources_per_env_runner: dict[str, Annotated[float, Field(gt=0)]] = Field(default_factory=dict)
    """Custom Ray resources each env runner needs, e.g. ``{sampler: 1}`` to place runners
    on the nodes started with that resource (``ray start --resources``)."""
    sampler: Literal["fast", "batched", "standard"] = "fast"
    """``fast``: runners step their games as arrays and build PPO's batch from them; ``batched``: those games as RLlib
    episodes; ``standard``: RLlib's ``MultiAgentEnvRunner``. The same PPO; the last two are kept to compare."""
    torch_threads: int | None = Field(None, ge=1)
    """Torch threads in every process that runs torch (driver, env runners, evaluation workers); ``None``: the CPUs
    given to that process, at least 1."""
    sample_ahead: bool = False
    """The env runners sample each iteration's batch while the driver's learner updates on the last one, by the policy
    one update old (as APPO; ``league.rllib.algorithm.LeaguePPO.step_ahead``), the clip anchored at the learner's own
    policy (decoupled PPO). Needs ``resources.num_env_runners`` >= 1
    and ``resources.sampler: fast``."""

    def threads_for(self, cpus: float) -> int:
        """Torch threads of a process that was given ``cpus`` CPUs."""
        return self.torch_threads or max(1, int(cpus))


class ScriptedTeam(Strict):
    """A scripted team: one scripted targeter and one scripted defender."""

    targeter: str = PAPER_TEAM["targeter"]
    """The scripted targeter (``envs.scripted``)."""
    defender: str = PAPER_TEAM["defender"]
    """The scripted defender (``envs.scripted``)."""

    @model_validator(mode="after")
    def _known(self) -> "ScriptedTeam":
        for agent, name in (("targeter", self.targeter), ("defender", self.defender)):
            if name not in PLAYERS[agent]:
                raise ValueError(f"unknown scripted {agent} {name!r}; expected one of {sorted(PLAYERS[agent])}")
        return self


class ProtocolPhase(Strict):
    """One phase of the paper's protocol: one side learns against the other side's pool."""

    learner: Side
    """Which side learns in this phase."""
    episodes: int | None = Field(None, ge=1)
    """The phase ends once its learner has played this many episodes..."""
    env_steps: int | None = Field(None, ge=1)
    """...or, given instead, once this many env steps were sampled in it (a budget that does not
    depend on how long the games last)."""
    opponents: Literal["scripted", "latest", "scripted_and_latest", "scripted_and_snapshots"] = "scripted"
    """``scripted``: the scripted players; ``latest``: the other side's newest snapshot (the paper's phase 2); by PFSP,
    ``scripted_and_latest``: both, ``scripted_and_snapshots``: the scripted players and every snapshot."""

    @model_validator(mode="after")
    def _one_budget(self) -> "ProtocolPhase":
        if (self.episodes is None) == (self.env_steps is None):
            raise ValueError("a protocol phase needs exactly one budget: `episodes` or `env_steps`")
        return self


class DoubleOracle(Strict):
    """PSRO's step in a self-play league (``league.training.oracle``): at each self-play phase's end a
    best response of the phase's side, trained from the run's prior against the other side's
    meta-strategy, joins its side's pool and the meta-game as a frozen player (kind ``oracle``)."""

    env_steps: int = Field(0, ge=0)
    """Env steps each phase's best response trains for; 0: no double-oracle step."""
    meta_solver: Literal["nash", "regret_matching"] = "nash"
    """Each side's meta-strategy, what the other side's best response trains against (and ``pfsp: nash``'s weights):
    the meta-game's Nash mixture, or regret matching against the other side's best responses (Anytime PSRO)."""


class LeagueSettings(Strict):
    """Who is in the league, who learns when, against whom, and when a phase ends."""

    mode: Literal["protocol", "selfplay"] = "selfplay"
    """``protocol``: the paper's phases in order (``phases``); ``selfplay``: alternating phases against the whole pool."""
    phases: list[ProtocolPhase] = Field(default_factory=list)
    """Protocol mode: the phases in order."""
    selfplay_phases: int = Field(6, ge=1)
    """Self-play mode: how many alternating phases (attacker first)."""
    snapshot_win_rate: float = Field(0.6, gt=0, le=1)
    """A self-play phase ends with a snapshot once the learner wins this often in it..."""
    min_phase_episodes: int = Field(200, ge=1)
    """...over at least this many episodes..."""
    phase_env_steps: int = Field(100_000, ge=1)
    """...or once it has sampled this many env steps."""
    team_phase_env_steps: int | None = Field(None, ge=1)
    """Self-play mode: the team's phases end after this many env steps instead (default:
    ``phase_env_steps``); an attacker phase's budget is shared by its attackers, the team's is its own."""
    pfsp: Literal["squared", "variance", "uniform", "nash"] = "squared"
    """Opponent weighting on the learner's win rate x: (1 - x)^2, x (1 - x) or flat; or ``nash``, PSRO's rule: the other
    side's Nash mixture in the meta-game of the frozen players ([training.md](training.md))."""
    scripted_share: dict[Side, Annotated[float, Field(ge=0, le=1)]] = Field(default_factory=dict)
    """Per side, the share of its learners' games held for the other side's scripted players, spread by
    ``scripted_weighting``; PFSP draws the rest over the whole pool. Empty: PFSP alone."""
    scripted_weighting: Literal["pfsp", "uniform"] = "pfsp"
    """How ``scripted_share`` is spread over the scripted players: by the ``pfsp`` weighting, or evenly (``uniform``),
    so that one the learner always beats (no games under ``squared``) is still met."""
    attacker_reward_methods: list[Literal[1, 2, 3]] | None = None
    """Train one attacker per listed reward method side by side; default: ``game.attacker_reward`` only."""
    exploiters: list[Side] = Field(default_factory=list)
    """Self-play mode: the sides whose learners each get an exploiter twin (AlphaStar's main exploiter), trained against
    the other side's newest snapshots, frozen into its pool at each phase end ([training.md](training.md))."""
    exploiter_phases: Literal["all", "final", "all_and_final"] = "all"
    """With ``exploiters``: ``all``, they train in every phase of their side; ``final``, only in one more phase after
    the self-play phases, each from its untrained policy, against the final snapshots; ``all_and_final``, both."""
    exploiters_restart: bool = False
    """Self-play mode: each exploiter starts each of its phases after the first from its learner's version 0, with a new
    optimizer state, as AlphaStar resets its main exploiters; ``false``: it trains on from phase to phase."""
    frozen_players_explore: bool = True
    """In training, frozen snapshots sample their actions (``true``) or play their policy's mean (``false``, as every
    player does in evaluation). ``false`` needs ``resources.sampler: fast`` or ``batched``."""
    scripted_attackers: list[str] = Field(default_factory=lambda: ["lead_intercept"])
    """Scripted attackers in the league (``envs.scripted``): training opponents of the team and members of the meta-game."""
    scripted_teams: list[ScriptedTeam] = Field(default_factory=lambda: [ScriptedTeam()])
    """Scripted teams (a targeter and a defender each) in the league: training opponents of the attackers and members of the meta-game."""
    double_oracle: DoubleOracle = Field(default_factory=DoubleOracle)

    @field_validator("exploiters")
    @classmethod
    def _exploiters_in_selfplay(cls, sides: list[str], info: ValidationInfo) -> list[str]:
        if sides and info.data.get("mode") == "protocol":
            raise ValueError("exploiters train in self-play only (mode: selfplay); leave league.exploiters empty in protocol mode")
        if len(set(sides)) != len(sides):
            raise ValueError("league.exploiters must list each side at most once")
        return sides

    @model_validator(mode="after")
    def _check(self) -> "LeagueSettings":
        for name in self.scripted_attackers:
            if name not in PLAYERS["attacker"]:
                raise ValueError(f"unknown scripted attacker {name!r}; expected one of {sorted(PLAYERS['attacker'])}")
        if self.mode == "protocol" and not self.phases:
            raise ValueError("protocol mode needs at least one entry in `phases`")
        if self.mode == "protocol" and self.phases[0].opponents != "scripted":
            raise ValueError("the first protocol phase has no snapshot to play: use opponents: scripted")
        if self.attacker_reward_methods is not None and (
            not self.attacker_reward_methods or len(set(self.attacker_reward_methods)) != len(self.attacker_reward_methods)
        ):
            raise ValueError("attacker_reward_methods must list distinct methods (1, 2, 3), at least one")
        if not self.scripted_attackers or not self.scripted_teams:
            raise ValueError("the league needs at least one scripted attacker and one scripted team")
        if self.double_oracle.env_steps and self.mode != "selfplay":
            raise ValueError("league.double_oracle.env_steps follows self-play phases: set league.mode: selfplay, or 0")
        if self.double_oracle.meta_solver != "nash" and not self.double_oracle.env_steps:
            raise ValueError("league.double_oracle.meta_solver: regret_matching plays against the double oracle's best "
                             "responses: set league.double_oracle.env_steps")
        if self.exploiter_phases != "all":
            follows = "attacker" if self.selfplay_phases % 2 == 0 else "team"
            if self.mode != "selfplay" or self.exploiters != [follows]:
                raise ValueError(
                    f"league.exploiter_phases: {self.exploiter_phases} trains the exploiters of the side that follows the last "
                    f"self-play phase: set league.exploiters to [{follows}] (mode: selfplay)"
                )
        return self


class EvaluationSettings(Strict):
    """The fixed dev games (envs.scenarios): the final evaluation, evaluations during training and learning curves."""

    episodes: int = Field(1000, ge=1)
    """Fixed seeded games per evaluated pair."""
    workers: int = Field(2, ge=0)
    """Ray actors that play the evaluation games (0: in the driver process)."""
    cpus_per_worker: float = Field(0.5, gt=0)
    """CPUs Ray reserves for each evaluation worker."""
    custom_resources_per_worker: dict[str, Annotated[float, Field(gt=0)]] = Field(default_factory=dict)
    """Custom Ray resources each evaluation worker needs (workers are spread over the nodes)."""
    every_iterations: int = Field(0, ge=0)
    """Also evaluate the learners against their opponents every this many iterations (0: only at the end)."""
    curve_every_env_steps: int = Field(20_000, ge=0)
    """Learning curves: each time a learner passes another multiple of this many env steps, it plays its curve opponents
    on the first ``curve_episodes`` dev games (``league.evaluation.learning_curves``); 0: no curves."""
    curve_episodes: int = Field(200, ge=1)
    """Fixed evaluation games per learning-curve point (and per reference line)."""


class RunConfig(Strict):
    """One run: a config file of ``configs/``, its sections below."""

    name: str = Field(min_length=1)
    """The run's name: the prefix of its default run directory (``runs/NAME-TIME``)."""
    seed: int = Field(0, ge=0, lt=2**32)
    """Seeds every generator of the run; RLlib passes it to ``np.random.seed``, hence the bound."""
    game: GameConfig = Field(default_factory=GameConfig)
    ppo: PPOSettings = Field(default_factory=PPOSettings)
    resources: Resources = Field(default_factory=Resources)
    league: LeagueSettings = Field(default_factory=LeagueSettings)
    evaluation: EvaluationSettings = Field(default_factory=EvaluationSettings)
    checkpoint_every: int = Field(1, ge=1)
    """Iterations between checkpoints; a resume restarts from the last one."""

    @model_validator(mode="after")
    def _check(self) -> "RunConfig":
        schedule = self.ppo.lr_schedule
        if schedule is not None and (schedule[0][0] != 0 or any(a[0] >= b[0] for a, b in zip(schedule, schedule[1:]))):
            raise ValueError("ppo.lr_schedule must start at 0 env steps and list increasing env steps")
        for key in ("attacker_prior", "team_prior"):
            if getattr(self.ppo, key) != "none" and (self.game.observation, self.game.action_mode) != ("rich", "relative"):
                raise ValueError(f"ppo.{key} needs game.observation: rich and game.action_mode: relative")
        if self.ppo.attacker_residual_penalty and self.ppo.attacker_prior == "none":
            raise ValueError("ppo.attacker_residual_penalty needs ppo.attacker_prior (it weighs the correction of a prior)")
        if self.ppo.attacker_residual_penalty_gate != "always" and not self.game.attacker_memory:
            raise ValueError("ppo.attacker_residual_penalty_gate: until_targeter_turns needs game.attacker_memory")
        for key in ("attacker_heading_cosines", "attacker_scripted_turns"):
            if getattr(self.ppo, key) and self.game.observation != "rich":
                raise ValueError(f"ppo.{key} needs game.observation: rich")
        if self.ppo.minibatch_size > self.ppo.train_batch_size:
            raise ValueError("ppo.minibatch_size must not exceed ppo.train_batch_size")
        if self.ppo.minibatch_counts != "rows" and self.resources.sampler != "fast":
            raise ValueError("ppo.minibatch_counts: env_steps needs resources.sampler: fast (RLlib's PPO has one minibatch size)")
        if self.ppo.team_num_epochs is not None and self.resources.sampler != "fast":
            raise ValueError("ppo.team_num_epochs needs resources.sampler: fast (RLlib's PPO has one epoch count)")
        if self.ppo.team_reward != "own" and self.resources.sampler != "fast":
            raise ValueError("ppo.team_reward: shared needs resources.sampler: fast (RLlib's learner pays each agent its own reward)")
        for key in ("targeter_shaping", "defender_shaping", "attacker_win_reward", "attacker_residual_penalty", "bf16",
                    "compile_loss"):
            if getattr(self.ppo, key) and self.resources.sampler != "fast":
                raise ValueError(f"ppo.{key} needs resources.sampler: fast (RLlib's learner connectors would not apply it)")
        if self.resources.sample_ahead and (self.resources.num_env_runners < 1 or self.resources.sampler != "fast"):
            raise ValueError(
                "resources.sample_ahead needs resources.num_env_runners >= 1 (remote runners sample while the driver "
                "learns) and resources.sampler: fast"
            )
        if not self.league.frozen_players_explore and self.resources.sampler == "standard":
            raise ValueError(
                "league.frozen_players_explore: false needs resources.sampler: fast or batched "
                "(RLlib's standard runner samples every module alike)"
            )
        if self.ppo.discount("team") != self.ppo.discount("attacker") and self.resources.sampler != "fast":
            raise ValueError(
                "ppo.team_gamma and ppo.team_lambda_ need resources.sampler: fast "
                "(RLlib's learner computes GAE with one gamma and lambda for every module)"
            )
        return self

    @property
    def attacker_methods(self) -> list[int]:
        """The reward methods of the learning attackers."""
        return list(self.league.attacker_reward_methods or [self.game.attacker_reward])


def resolve_path(name: str) -> Path:
    """A path as given, or a bare name looked up in ``configs/`` (``.yaml`` optional)."""
    path = Path(name)
    if path.exists():
        return path
    for candidate in (CONFIG_DIR / name, CONFIG_DIR / f"{name}.yaml"):
        if candidate.exists():
            return candidate
    raise ConfigError(f"config {name!r} not found (looked in the working directory and {CONFIG_DIR})")


def _set_dotted(data: dict[str, Any], dotted: str, value: Any) -> None:
    keys = dotted.split(".")
    node = data
    for key in keys[:-1]:
        node = node.setdefault(key, {})
        if not isinstance(node, dict):
            raise ConfigError(f"--set {dotted}: {key!r} is not a section")
    node[keys[-1]] = value


def _read_yaml(path: Path) -> dict[str, Any]:
    if not path.exists():
        raise ConfigError(f"{path} is missing")
    if not path.is_file():
        raise ConfigError(f"{path} is a directory, not a YAML file" if path.is_dir() else f"{path} is not a file")
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        raise ConfigError(f"{path}: not valid YAML ({where}{err.problem or err.context})") from err
    except (yaml.YAMLError, UnicodeDecodeError) as err:
        raise ConfigError(f"{path}: not valid YAML ({err})") from err
    except OSError as err:
        raise ConfigError(f"{path} cannot be read: {err.strerror}") from err
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: the top level must be a mapping of keys")
    return data


def _validate(data: dict[str, Any], source: Path, overrides: list[str] | None = None) -> RunConfig:
    try:
        return RunConfig.model_validate(data)
    except ValidationError as err:
        overridden = [item.partition("=")[0].strip() for item in overrides or []]
        problems = []
        for e in err.errors():
            key = ".".join(str(p) for p in e["loc"])
            # A problem with a key given with --set, inside it or in the section it names
            # (an unknown key, a section's own check), is reported as coming from --set.
            origin = next(
                (
                    f"--set {item}"
                    for item, k in zip(overrides or [], overridden)
                    if (key and (key == k or key.startswith(k + ".") or k.startswith(key + ".")))
                    or (not key and k in e["msg"])  # a check across sections names its keys
                ),
                str(source),
            )
            hint = ""
            if e["type"] == "extra_forbidden":
                close = difflib.get_close_matches(str(e["loc"][-1]), _fields_at(e["loc"][:-1]), n=1)
                hint = f" (did you mean {'.'.join([*map(str, e['loc'][:-1]), close[0]])}?)" if close else ""
            problems.append(f"{origin}: {key or '(top level)'}: {e['msg']}{hint}")
        raise ConfigError("; ".join(problems)) from err


def _fields_at(loc: tuple) -> list[str]:
    """The keys of the config section at ``loc`` (``("ppo",)``: PPOSettings' fields)."""
    model: Any = RunConfig
    for part in loc:
        field = model.model_fields.get(str(part)) if isinstance(model, type) and issubclass(model, BaseModel) else None
        if field is None:
            return []
        model = field.annotation
    return list(model.model_fields) if isinstance(model, type) and issubclass(model, BaseModel) else []


def load_config(name: str, overrides: list[str] | None = None) -> RunConfig:
    """Read, override (``key.sub=value``, value parsed as YAML) and validate a config."""
    path = resolve_path(name)
    data = _read_yaml(path)
    for item in overrides or []:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--set {item!r}: expected key=value")
        try:
            value = yaml.safe_load(raw)
        except yaml.YAMLError as err:
            raise ConfigError(f"--set {item!r}: the value is not valid YAML ({getattr(err, 'problem', None) or err})") from err
        _set_dotted(data, key.strip(), value)
    return _validate(data, path, overrides)


def saved_run_config(run_dir: Path) -> RunConfig:
    """The config a run wrote into its directory when it started."""
    return _validate(_read_yaml(Path(run_dir) / RUN_CONFIG_FILE), Path(run_dir) / RUN_CONFIG_FILE)


def config_hash(run: RunConfig) -> str:
    """A digest of the validated config: what a resume compares to detect an edited ``config.yaml``."""
    canonical = json.dumps(run.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()


def changed_keys(old: dict[str, Any], new: dict[str, Any], prefix: str = "") -> list[str]:
    """Dotted keys whose values differ between two dumped configs."""
    changed = []
    for key in sorted(set(old) | set(new), key=str):
        a, b = old.get(key), new.get(key)
        if isinstance(a, dict) and isinstance(b, dict):
            changed += changed_keys(a, b, f"{prefix}{key}.")
        elif a != b:
            changed.append(f"{prefix}{key}")
    return changed


def added_at_its_default(old: dict[str, Any], new: dict[str, Any], key: str) -> bool:
    """Whether the dotted ``key`` is missing from ``old`` (a config dumped by a version without
    that key) and ``new`` (a ``RunConfig`` dumped) has the key's default, the behaviour of the
    versions before it."""
    *sections, name = key.split(".")
    model: Any = RunConfig
    value: Any = new
    for section in sections:
        if section not in old:
            return False
        old, value, model = old[section], value[section], model.model_fields[section].annotation
    if name in old or name not in model.model_fields:
        return False
    field = model.model_fields[name]
    default = TypeAdapter(field.annotation).dump_python(field.get_default(call_default_factory=True), mode="json")
    return value[name] == default


def _type_name(annotation: Any) -> str:
    """A key's type as a reader writes it: ``float | None``, ``'fast' | 'batched'``, ``list[str]``."""
    origin, args = get_origin(annotation), get_args(annotation)
    if origin is Annotated:
        return _type_name(args[0])
    if origin in (Union, types.UnionType):
        return " | ".join(_type_name(a) for a in args)
    if origin is Literal:
        return " | ".join(repr(a) for a in args)
    if origin in (list, dict, tuple):
        return f"{origin.__name__}[{', '.join(_type_name(a) for a in args)}]"
    return "None" if annotation is type(None) else getattr(annotation, "__name__", str(annotation))


def _sections(model: type[BaseModel], prefix: str) -> list[tuple[str, type[BaseModel]]]:
    """``(dotted key, model)`` of ``model`` and every section below it, lists of sections included."""
    found = [(prefix, model)]
    for name, field in model.model_fields.items():
        inner = field.annotation
        listed = getattr(inner, "__origin__", None) is list
        if listed:
            inner = inner.__args__[0]
        if isinstance(inner, type) and issubclass(inner, BaseModel):
            found += _sections(inner, f"{prefix}{name}{'[]' if listed else ''}.")
    return found


def undocumented_fields(model: type[BaseModel] = RunConfig) -> list[str]:
    """Dotted keys of every config key without a field docstring (the reference would leave them blank)."""
    return [
        f"{prefix}{name}"
        for prefix, section in _sections(model, "")
        for name, field in section.model_fields.items()
        if not (field.description or "").strip() and not _is_section(field)
    ]


def _is_section(field: Any) -> bool:
    return isinstance(field.annotation, type) and issubclass(field.annotation, BaseModel)


def reference_markdown(model: type[BaseModel] = RunConfig) -> str:
    """Every config key with its type, default and docstring, one table per section (``docs/configuration.md``)."""
    out = [
        "# Configuration reference",
        "",
        "Every key of a run config (`configs/*.yaml`), generated from the pydantic models of",
        "`league/config.py` and `envs/config.py` (`tests/commands/test_config_reference.py` fails when this page and",
        "the code differ; regenerate with `python -m league.config_reference > docs/configuration.md`).",
        "Unknown keys are errors; `--set key.sub=value` overrides any key from the command line.",
    ]
    for prefix, section in _sections(model, ""):
        out += ["", f"## `{prefix.rstrip('.') or '(top level)'}`", "", " ".join((section.__doc__ or "").split()), "",
                "| key | type | default | meaning |", "| --- | --- | --- | --- |"]
        for name, field in section.model_fields.items():
            if _is_section(field):
                out.append(f"| `{name}` | section | | [`{prefix}{name}`](#{prefix.replace('.', '')}{name}) below |")
                continue
            default = "required" if field.is_required() else repr(field.get_default(call_default_factory=True))
            meaning = " ".join((field.description or "").split()).replace("|", "\\|")
            kind = _type_name(field.annotation).replace("|", "\\|")  # GitHub tables split cells on | even in code
            out.append(f"| `{name}` | `{kind}` | `{default}` | {meaning} |")
    return "\n".join(out) + "\n"

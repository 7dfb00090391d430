"""Every reach into RLlib's internals, in one place, written for Ray ``RAY_VERSION`` (and the
one into torch's, for the CPU's bf16, and those into Ray core's, for joining a cluster).

RLlib's public API has no way to do what these functions do; each says what it reads or
writes and why the league needs it. No other module touches a private RLlib attribute or
writes an episode's internals (``tests/rllib/test_compat.py`` checks both, and pins the
Ray version): on a Ray upgrade, read this module against the new RLlib source first.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from ray.rllib.env.multi_agent_episode import MultiAgentEpisode
from ray.rllib.env.single_agent_episode import SingleAgentEpisode
from ray.rllib.env.utils.infinite_lookback_buffer import InfiniteLookbackBuffer
from ray.rllib.utils.metrics import (
    ALL_MODULES,
    MODULE_TRAIN_BATCH_SIZE_MEAN,
    NUM_ENV_STEPS_TRAINED,
    NUM_ENV_STEPS_TRAINED_LIFETIME,
    NUM_MODULE_STEPS_TRAINED,
    NUM_MODULE_STEPS_TRAINED_LIFETIME,
    WEIGHTS_SEQ_NO,
)

RAY_VERSION = "2.60.0"


# ---------------------------------------------------------------- torch (2.13)
def native_bf16() -> bool:
    """Whether this CPU multiplies bfloat16 natively (AMX or AVX-512 BF16); elsewhere torch
    emulates bf16 matmuls, slower than float32's. Torch tells only through private helpers."""
    return torch.cpu._is_amx_tile_supported() or torch.cpu._is_avx512_bf16_supported()


def inductor_compiler_found() -> bool:
    """Whether ``torch.compile``'s CPU backend finds the C++ compiler it builds its kernels with."""
    from torch._inductor.cpp_builder import get_cpp_compiler

    try:
        get_cpp_compiler()
    except Exception:  # torch raises its own errors for a compiler that is missing or unusable
        return False
    return True


# ---------------------------------------------------------------- Ray core (joining a cluster: league/cluster.py)
def gcs_address(address: str) -> str:
    """``host:port`` of the GCS that ``address`` names (``auto`` resolved), as ``ray.init`` resolves
    it; Ray's ``ConnectionError`` or ``ValueError`` if there is none."""
    from ray._private.services import canonicalize_bootstrap_address_or_die

    return canonicalize_bootstrap_address_or_die(address)


def ask_gcs(address: str) -> None:
    """Ask the GCS at ``address`` for its cluster id (blocks; Ray's ``AuthenticationError`` when it
    asks for a token this process does not send, ``RpcError`` when it does not answer)."""
    from ray._raylet import GcsClient

    GcsClient(address=address).cluster_id  # noqa: B018 (the property asks the GCS)


def has_auth_token() -> bool:
    """Whether this machine has a Ray token, where Ray looks for one whatever the auth mode."""
    from ray._raylet import AuthenticationTokenLoader

    return AuthenticationTokenLoader.instance().has_token(ignore_auth_mode=True)


def enable_token_auth() -> None:
    """Token mode for this process and the processes it starts: ``RAY_AUTH_MODE=token`` and Ray's
    cached config read again (what Ray's own ``_enable_token_auth`` does for ``address="auto"``)."""
    import os

    from ray._raylet import AuthenticationTokenLoader, Config

    os.environ["RAY_AUTH_MODE"] = "token"
    Config.initialize("")
    AuthenticationTokenLoader.instance().reset_cache()


def filter_driver_errors(keep: Any) -> None:
    """What Ray's error channel sends this driver (printed even with ``log_to_driver=False``)
    goes through ``keep(lines) -> lines`` first: ``print_to_stdstream`` of ``ray._private.worker``
    wrapped, for its messages from raylets, once per process."""
    import ray._private.worker as ray_worker

    original = ray_worker.print_to_stdstream
    if getattr(original, "filtered", False):
        return

    def print_to_stdstream(data: dict, ignore_prefix: bool) -> None:
        if data.get("pid") == "raylet":
            data = {**data, "lines": keep(data["lines"])}
            if not data["lines"]:
                return
        original(data, ignore_prefix)

    print_to_stdstream.filtered = True  # type: ignore[attr-defined]
    ray_worker.print_to_stdstream = print_to_stdstream


# ---------------------------------------------------------------- AlgorithmConfig
def has_custom_connectors(config: Any) -> bool:
    """Whether the config sets env-to-module or module-to-env connectors of its own.

    ``AlgorithmConfig`` keeps the user's connector factories in private fields only.
    """
    return config._env_to_module_connector is not None or config._module_to_env_connector is not None


# ---------------------------------------------------------------- EnvRunner (for a subclass of MultiAgentEnvRunner)
def weights_seq_no(env_runner: Any) -> int:
    """The sequence number of the weights the runner holds (set by RLlib's weight sync)."""
    return env_runner._weights_seq_no


def env_runner_seed(env_runner: Any) -> int | None:
    """The seed this runner's games start from (RLlib's reset seeds game ``i`` with it plus ``i``)."""
    return env_runner._seed


def set_env_runner_seed(env_runner: Any, seed: int) -> None:
    """Replace the seed RLlib derived for this runner (the config's seed plus the worker index)."""
    env_runner._seed = seed


def env_runner_callbacks(env_runner: Any) -> list[Any]:
    """The runner's callback objects, as ``make_callback`` wants them."""
    return env_runner._callbacks


def count_sampled_env_steps(env_runner: Any, env_steps: int) -> None:
    """Count ``env_steps`` in the runner's own sampled-steps counter, as RLlib's ``sample`` does."""
    env_runner._log_env_steps(metric=env_runner._metrics_num_env_steps_sampled, num_steps=env_steps)


# ---------------------------------------------------------------- Learner (for a subclass of RLlib's Learner)
def count_weights_update(learner: Any) -> None:
    """Advance the Learner's weights sequence number, as ``Learner.update`` does once per call
    (the EnvRunners' weight sync and the ``weights_seq_no`` metric read it)."""
    learner._weights_seq_no += 1


def gradients(learner: Any) -> dict[Any, Any]:
    """Every registered parameter's gradient by parameter reference, what
    ``TorchLearner.compute_gradients`` returns after its backward pass (the input of RLlib's
    ``postprocess_gradients`` and ``apply_gradients``)."""
    return {ref: param.grad for ref, param in learner._params.items()}


def log_trained_minibatches(learner: Any, rows: dict[str, int], env_steps: int, count: int) -> None:
    """Count ``count`` trained minibatches of ``rows[module_id]`` rows per module (and the
    batch's ``env_steps`` each, as RLlib counts a minibatch) in the Learner's metrics and Ray
    metrics, with the results of ``Learner.update`` calling ``_log_metrics`` and
    ``_log_steps_trained_metrics`` after each: sums pushed as one total, the mean batch size
    and the weights sequence number (the same for every minibatch) once."""
    if env_steps > 0:
        learner._metrics_all_modules_num_env_steps_trained.inc(value=env_steps * count)
        learner._metrics_all_modules_num_module_steps_trained.inc(value=sum(rows.values()) * count)
    for module_id, size in rows.items():
        learner.metrics.log_value((module_id, WEIGHTS_SEQ_NO), learner._weights_seq_no, window=1)
        learner.metrics.log_value((module_id, MODULE_TRAIN_BATCH_SIZE_MEAN), size, reduce="mean")
        learner.metrics.log_value((module_id, NUM_MODULE_STEPS_TRAINED), size * count, reduce="sum")
        learner.metrics.log_value(
            (module_id, NUM_MODULE_STEPS_TRAINED_LIFETIME), size * count, reduce="lifetime_sum", with_throughput=True
        )
        learner.metrics.log_value((ALL_MODULES, NUM_MODULE_STEPS_TRAINED), size * count, reduce="sum", with_throughput=True)
        learner.metrics.log_value(
            (ALL_MODULES, NUM_MODULE_STEPS_TRAINED_LIFETIME), size * count, reduce="lifetime_sum", with_throughput=True
        )
    learner.metrics.log_value((ALL_MODULES, NUM_ENV_STEPS_TRAINED), env_steps * count, reduce="sum", with_throughput=True)
    learner.metrics.log_value(
        (ALL_MODULES, NUM_ENV_STEPS_TRAINED_LIFETIME), env_steps * count, reduce="lifetime_sum", with_throughput=True
    )


# ---------------------------------------------------------------- episodes
def lockstep_episode(
    episode: MultiAgentEpisode, agent_episodes: dict[str, SingleAgentEpisode], env_t: int, length: int, terminated: bool
) -> MultiAgentEpisode:
    """``episode`` (new, empty, started at env step ``env_t``) holding ``agent_episodes``,
    ``length`` steps in which every agent acted on every env step.

    ``MultiAgentEpisode`` is built step by step through ``add_env_step``; a whole chunk of
    numpy data is set here at once: the per-agent episodes, the env time, each agent's
    env-to-agent time map (the identity) and the termination flag.
    """
    episode.agent_episodes = agent_episodes
    episode.env_t = env_t + length
    for agent in agent_episodes:
        episode.agent_t_started[agent] = env_t
        episode.env_t_to_agent_t[agent] = InfiniteLookbackBuffer(list(range(env_t, env_t + length + 1)))
    episode.is_terminated = terminated  # the data went in as numpy arrays: no `to_numpy()` needed
    return episode


def overwrite_rewards(agent_episode: SingleAgentEpisode, rewards: list[float]) -> None:
    """Replace the first ``len(rewards)`` rewards of an agent's episode.

    A finalized (numpy) buffer is written in place: ``set_rewards`` checks every value
    against a space, about 0.1 ms per episode.
    """
    buffer = agent_episode.rewards
    if buffer.finalized:
        buffer.data[buffer.lookback : buffer.lookback + len(rewards)] = rewards
    else:
        agent_episode.set_rewards(new_data=np.array(rewards, dtype=np.float32), at_indices=slice(0, len(rewards)))

"""RLlib behind one adapter: internals only in ``league.rllib.compat``, pinned to the Ray version.

``league/rllib/compat.py`` holds every read or write of RLlib's private attributes and
episode internals; ``league/rllib/bridge.py`` (the adapter) and ``league/rllib/algorithm.py``
(its algorithm) every checkpoint load and every parse of ``train()`` results. The scans below check the source tree for that, and
each is shown to find a planted violation.
"""

from __future__ import annotations

import importlib
import inspect
import io
import re
import tokenize

import ray

from league.rllib import compat as rllib_compat
from tests.test_layering import ROOT, plant, source_files

COMPAT = "league/rllib/compat.py"
ADAPTER = {"league/rllib/bridge.py", "league/rllib/algorithm.py"}  # the adapter and its algorithm
# Modules whose classes subclass RLlib's (EnvRunner, Algorithm, Learner, RLModule, callbacks, connectors).
RLLIB_SUBCLASSING = (
    "league.rllib.env_runner", "league.rllib.algorithm", "league.rllib.learner", "league.rllib.callbacks", "league.rllib.modules",
)
# Writes of a MultiAgentEpisode's internals (what RLlib's add_env_step keeps consistent), on
# the names our code gives episodes.
EPISODE_INTERNALS = re.compile(
    r"\b(?:\w*episode\w*|chunk)\.(agent_episodes|env_t|agent_t_started|env_t_to_agent_t|is_terminated)\b[^=\n]*=(?!=)"
)
# RLModule's documented extension points: private by name, overridden by design.
OVERRIDE_HOOKS = {"_forward", "_forward_train", "_forward_exploration", "_forward_inference"}
CHECKPOINTS_AND_RESULTS = re.compile(r"\bfrom_checkpoint\b|\bLEARNER_RESULTS\b|\[\s*[\"']learners[\"']\s*\]")


def test_written_for_the_installed_ray():
    # On a Ray upgrade: read league/rllib/compat.py against the new RLlib source, then move the pin.
    assert ray.__version__ == rllib_compat.RAY_VERSION


def foreign_private_attributes(text: str) -> list[str]:
    """``obj._name`` where ``obj`` is not ``self`` or ``cls``: code tokens only, strings and comments skipped."""
    tokens = [t for t in tokenize.generate_tokens(io.StringIO(text).readline) if t.type not in (tokenize.NL, tokenize.NEWLINE)]
    found = []
    for before, dot, name in zip(tokens, tokens[1:], tokens[2:]):
        if dot.string == "." and name.type == tokenize.NAME and re.match(r"_[a-z]", name.string):
            if before.string not in ("self", "cls"):
                found.append(f"{before.string}.{name.string} (line {name.start[0]})")
    return found


def scan(root, check, allowed: set[str]) -> dict[str, list[str]]:
    found = {}
    for path in source_files(root):
        relative = path.relative_to(root).as_posix()
        if relative not in allowed:
            hits = check(path.read_text())
            if hits:
                found[relative] = hits
    return found


def test_no_private_attribute_of_another_object_outside_the_compat_module():
    assert scan(ROOT, foreign_private_attributes, {COMPAT}) == {}


def test_no_episode_internals_written_outside_the_compat_module():
    assert scan(ROOT, lambda text: EPISODE_INTERNALS.findall(text), {COMPAT}) == {}


def test_checkpoints_and_learner_results_only_in_the_adapter():
    assert scan(ROOT, lambda text: CHECKPOINTS_AND_RESULTS.findall(text), {*ADAPTER, COMPAT}) == {}


def rllib_private_names(cls: type) -> set[str]:
    """Private attributes and methods that the RLlib classes in ``cls``'s ancestry use."""
    names: set[str] = set()
    for base in cls.__mro__:
        if base.__module__.startswith("ray.rllib"):
            source = inspect.getsource(base)
            names |= set(re.findall(r"\bself\.(_[a-z]\w*)", source)) | set(re.findall(r"\bdef (_[a-z]\w*)", source))
    return names


def own_private_names(cls: type) -> set[str]:
    source = inspect.getsource(cls)
    return set(re.findall(r"\bself\.(_[a-z]\w*)", source)) | set(re.findall(r"\bdef (_[a-z]\w*)", source))


def test_subclasses_of_rllib_use_none_of_its_private_attributes():
    """Not through ``self`` either: a read depends on RLlib's internals, a same-named attribute
    or method of ours silently replaces RLlib's."""
    checked, used = [], {}
    for module_name in RLLIB_SUBCLASSING:
        module = importlib.import_module(module_name)
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if cls.__module__ != module_name or not any(b.__module__.startswith("ray.rllib") for b in cls.__mro__):
                continue
            checked.append(cls.__name__)
            clash = (own_private_names(cls) & rllib_private_names(cls)) - OVERRIDE_HOOKS
            if clash:
                used[cls.__name__] = sorted(clash)
    assert "BatchedEnvRunner" in checked and "LeaguePPO" in checked
    assert used == {}


def test_the_scans_find_planted_violations(tmp_path):
    root = plant(tmp_path, {
        COMPAT: "seed = runner._seed\n",
        "league/runner.py": 'x = config._env_to_module_connector  # reads a private field\ny = "ray._common"\n',
        "league/chunk.py": "episode.env_t = 3\nepisode.is_terminated = True\nok = episode.env_t == 3\n",
        "league/rollout/games.py": "self.env_t[game] = 0  # the rollout's own counter, not an episode's\n",
        "league/run.py": "algo = Algorithm.from_checkpoint(path)\nstats = result['learners']\n",
    })
    assert scan(root, foreign_private_attributes, {COMPAT}) == {"league/runner.py": ["config._env_to_module_connector (line 1)"]}
    assert scan(root, lambda text: EPISODE_INTERNALS.findall(text), {COMPAT}) == {"league/chunk.py": ["env_t", "is_terminated"]}
    assert scan(root, lambda text: CHECKPOINTS_AND_RESULTS.findall(text), {*ADAPTER, COMPAT}) == {
        "league/run.py": ["from_checkpoint", "['learners']"]
    }

    from ray.rllib.env.multi_agent_env_runner import MultiAgentEnvRunner

    class Shadowing(MultiAgentEnvRunner):
        def _new_episode(self, game):  # replaces RLlib's own _new_episode
            return self._weights_seq_no

    assert own_private_names(Shadowing) & rllib_private_names(Shadowing) == {"_new_episode", "_weights_seq_no"}

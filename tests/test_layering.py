"""Where things may live: the rules of the layout, checked on the source tree.

SQL only in the store; no import cycles among the modules of ``envs/`` and ``league/`` or league's
packages (an import under ``if TYPE_CHECKING`` counts); no module
imports a command (the modules at the top of ``league/`` with a ``__main__`` block);
``league/core/`` without Ray or torch; the league's decision module (``league/core/league.py``) without
the store, Ray or RLlib; ``ray.rllib`` only in ``league/rllib/``; who won only in
``league/core/payoff.py``; training rewards assembled only in ``league/rollout/``; RLlib's ``model_config``
read only by ``league/rllib/module_settings.py``; the README's layout table lists the packages,
docs/architecture.md's every module; no class in ``league/`` over 250 lines, no function over 8 parameters.

Each rule is a scan of the source files (``envs/``, ``league/``, ``bench/``) and a test
that the scan finds a planted violation, so a rule that stopped matching would fail.
Tests themselves are not scanned: they read ``league.db`` with their own SQL on
purpose, as a check of what is on disk that does not go through the store's code.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SOURCE_DIRS = ("envs", "league", "bench")

# Running SQL: the sqlite3 module, a cursor's execute calls, or an SQL statement in a string.
SQL = re.compile(
    r"\bimport sqlite3\b|\bfrom sqlite3\b|\.execute(many|script)?\("
    r"|\bSELECT\b[^\n]*\bFROM\b|\bINSERT\s+(OR\s+\w+\s+)?INTO\b|\bUPDATE\s+\w+\s+SET\b|\bDELETE\s+FROM\b"
    r"|\b(CREATE|ALTER|DROP)\s+TABLE\b"
)
SQL_HOME = "league/state/store.py"


def source_files(root: Path) -> list[Path]:
    return sorted(p for d in SOURCE_DIRS for p in (root / d).rglob("*.py"))


def violations(root: Path, pattern: re.Pattern, allowed: set[str]) -> list[str]:
    """``path:line: text`` of every line matching ``pattern`` outside the ``allowed`` files."""
    found = []
    for path in source_files(root):
        relative = path.relative_to(root).as_posix()
        if relative in allowed:
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if pattern.search(line):
                found.append(f"{relative}:{number}: {line.strip()}")
    return found


def plant(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return root


def test_sql_only_in_the_store():
    assert violations(ROOT, SQL, {SQL_HOME}) == []


def test_the_sql_scan_finds_sql_outside_the_store(tmp_path):
    root = plant(tmp_path, {
        SQL_HOME: 'import sqlite3\nROWS = "SELECT id FROM players"\n',
        "league/report.py": 'rows = store.db.execute("SELECT outcome, SUM(count) FROM matches").fetchall()\n',
        "bench/learning.py": "import sqlite3\n",
        "envs/core.py": 'Q = "UPDATE players SET env_steps = 0"\n',
        "league/status.py": '"""Selects the players from the store."""\n',  # prose, not SQL
    })
    assert [v.split(":")[0] for v in violations(root, SQL, {SQL_HOME})] == [
        "bench/learning.py", "envs/core.py", "league/report.py",
    ]


# ---------------------------------------------------------------- the import graph of league/
def module_name(root: Path, path: Path) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules_of(root: Path, packages: tuple[str, ...]) -> dict[str, Path]:
    """Module name -> file, for every module under the top-level ``packages``."""
    return {module_name(root, p): p for package in packages for p in sorted((root / package).rglob("*.py"))}


def imports_of(path: Path, modules: set[str]) -> set[str]:
    """Every module ``path`` imports, at module level or inside a function; ``from P import m``
    counts as importing ``P.m`` where that is a module (and ``P`` only where a name is not)."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            submodules = {f"{node.module}.{alias.name}" for alias in node.names} & modules
            found |= submodules
            if len(submodules) < len(node.names):  # something taken from the package's ``__init__``
                found.add(node.module)
    return found


def import_graph(root: Path) -> dict[str, set[str]]:
    """Module of ``envs/`` or ``league/`` -> those it imports (a package's ``__init__`` counts only when named)."""
    modules = modules_of(root, ("envs", "league"))
    return {name: (imports_of(path, set(modules)) & set(modules)) - {name} for name, path in modules.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan): each holds a cycle."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for other in sorted(graph.get(node, ())):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def package_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """The same edges between ``league``'s sub-packages (a top-level module is its own node)."""

    def package(name: str) -> str:
        return ".".join(name.split(".")[:2])

    packages: dict[str, set[str]] = {}
    for name, imported in graph.items():
        packages.setdefault(package(name), set()).update(package(i) for i in imported if package(i) != package(name))
    return packages


def commands(root: Path) -> set[str]:
    """The commands: modules at the top of ``league/`` run as ``python -m league.NAME``."""
    return {module_name(root, p) for p in (root / "league").glob("*.py") if MAIN_BLOCK.search(p.read_text())}


MAIN_BLOCK = re.compile(r'^if __name__ == ["\']__main__["\']:', re.MULTILINE)


def command_imports(root: Path) -> list[str]:
    """``importer -> command`` for every import of a command by a library module or by another command."""
    graph, run_as_commands = import_graph(root), commands(root)
    return sorted(f"{name} -> {i}" for name, imported in graph.items() for i in imported if i in run_as_commands)


def test_no_import_cycles_among_modules_or_packages():
    graph = import_graph(ROOT)
    assert len(graph) > 40 and "league.rllib.bridge" in graph["league.training.coordinator"]
    assert cycles(graph) == []
    assert cycles(package_graph(graph)) == []


def test_the_cycle_scan_finds_a_planted_circle(tmp_path):
    root = plant(tmp_path, {
        "league/__init__.py": "",
        "league/analysis/__init__.py": "",
        "league/reports/__init__.py": "",
        "league/analysis/exploitability.py": "def interval():\n    from league.reproduce import bootstrap_interval\n",
        "league/reproduce.py": "from league.reports.data import PAPER_TABLE_1\n",
        "league/reports/data.py": "from league.analysis import exploitability\n",
        "league/reports/plots.py": "from league.reports.data import PAPER_TABLE_1\n",  # within a package: fine
        "envs/__init__.py": "",
        "envs/scripted.py": "from envs.theory_players import attacker_apollonius\n",
        "envs/theory_players.py": "if TYPE_CHECKING:\n    from envs.scripted import GameView\n",
    })
    assert cycles(import_graph(root)) == [
        ["envs.scripted", "envs.theory_players"],
        ["league.analysis.exploitability", "league.reports.data", "league.reproduce"],
    ]
    assert cycles(package_graph(import_graph(root))) == [
        ["envs.scripted", "envs.theory_players"],
        ["league.analysis", "league.reports", "league.reproduce"],
    ]


def test_no_module_imports_a_command():
    assert commands(ROOT) >= {"league.run", "league.status", "league.report", "league.exploit", "league.curves"}
    assert not commands(ROOT) & {"league.cli", "league.config"}
    assert command_imports(ROOT) == []


def test_the_command_scan_finds_a_planted_import(tmp_path):
    root = plant(tmp_path, {
        "league/evaluate.py": 'def count(n):\n    return n\n\nif __name__ == "__main__":\n    pass\n',
        "league/replay.py": 'from league.evaluate import count\nif __name__ == "__main__":\n    pass\n',
        "league/training/coordinator.py": "def table():\n    from league.evaluate import count\n",
        "league/cli.py": "def count(n):\n    return n\n",
        "league/exploit.py": 'from league.cli import count\nif __name__ == "__main__":\n    pass\n',  # fine
    })
    assert command_imports(root) == ["league.replay -> league.evaluate", "league.training.coordinator -> league.evaluate"]


# ---------------------------------------------------------------- who may import what outside league/
def external_imports(root: Path, prefix: str, under: str) -> list[str]:
    """``module: import`` of every import of ``prefix`` (or below it) by a module of ``league/`` outside ``under``,
    or, for ``under`` ending in ``!``, by a module inside it."""
    inside = under.endswith("!")
    under = under.rstrip("!")
    found = []
    for name, path in modules_of(root, ("league",)).items():
        if (name == under or name.startswith(under + ".")) != inside:
            continue
        for imported in imports_of(path, set()):
            if imported == prefix or imported.startswith(prefix + "."):
                found.append(f"{name}: {imported}")
    return sorted(found)


def test_core_imports_neither_ray_nor_torch():
    graph = import_graph(ROOT)
    core = {name for name in graph if name.startswith("league.core")}
    reached = set(core)
    while True:  # and nor does any league module core imports
        more = {i for name in reached for i in graph[name]} - reached
        if not more:
            break
        reached |= more
    found = [hit for library in ("ray", "torch") for name in sorted(reached)
             for hit in external_imports(ROOT, library, name + "!")]
    assert "league.core.payoff" in reached and found == []


def test_only_the_rllib_package_imports_ray_rllib():
    assert external_imports(ROOT, "ray.rllib", "league.rllib!") != []
    assert external_imports(ROOT, "ray.rllib", "league.rllib") == []


def test_the_import_scans_find_planted_imports(tmp_path):
    root = plant(tmp_path, {
        "league/core/payoff.py": "import numpy as np\n\ndef fit():\n    import torch\n",
        "league/core/pfsp.py": "from ray import tune\n",
        "league/rllib/bridge.py": "from ray.rllib.algorithms.ppo import PPO\n",
        "league/training/coordinator.py": "from ray.rllib.core.columns import Columns\nimport ray\n",
    })
    assert external_imports(root, "torch", "league.core!") == ["league.core.payoff: torch"]
    assert external_imports(root, "ray", "league.core!") == ["league.core.pfsp: ray"]
    assert external_imports(root, "ray.rllib", "league.rllib") == ["league.training.coordinator: ray.rllib.core.columns"]


# ---------------------------------------------------------------- the league only decides
DECISION_MODULE = "league.core.league"
NOT_FOR_DECISIONS = ("league.state", "league.rllib")  # the store and run directory; the RLlib adapter


def decision_imports(root: Path) -> list[str]:
    """What the league's decision module reaches, itself or through the league modules it imports,
    of the store (``league.state``, ``sqlite3``), Ray or RLlib (Ray's or our adapter)."""
    graph = import_graph(root)
    reached, more = set(), {DECISION_MODULE}
    while more:
        reached |= more
        more = {i for name in more for i in graph.get(name, ())} - reached
    found = [f"{DECISION_MODULE} reaches {name}" for name in sorted(reached) if name.startswith(NOT_FOR_DECISIONS)]
    return found + [hit for library in ("ray", "sqlite3") for name in sorted(reached)
                    for hit in external_imports(root, library, name + "!")]


def test_the_league_decides_without_the_store_ray_or_rllib():
    assert DECISION_MODULE in import_graph(ROOT)
    assert decision_imports(ROOT) == []


def test_the_decision_scan_finds_a_planted_store_ray_and_rllib_import(tmp_path):
    root = plant(tmp_path, {
        "league/core/league.py": "from league.core import payoff\nfrom league.state.store import LeagueStore\n",
        "league/core/payoff.py": "def fit():\n    from league.rllib import bridge\n    import ray\n",
        "league/state/store.py": "import sqlite3\n",
        "league/rllib/bridge.py": "from ray.rllib.algorithms.ppo import PPO\n",
        "league/core/pfsp.py": "import ray\n",  # not reached from the decision module
    })
    assert decision_imports(root) == [
        "league.core.league reaches league.rllib.bridge", "league.core.league reaches league.state.store",
        "league.core.payoff: ray", "league.rllib.bridge: ray.rllib.algorithms.ppo", "league.state.store: sqlite3",
    ]


# ---------------------------------------------------------------- who won
# The flip of a result to one side's point of view, and the outcome labels the attacker wins:
# games minus the attacker's wins, "attacker" chosen by the attacker's win, a set of winning labels.
WHO_WON = re.compile(
    r"-\s*[\w.]*attacker_wins\b|[\"']attacker[\"']\s+if\s+[\w.]*attacker_w[io]n"
    r"|\bATTACKER_WINS\s*=|\bin\s+ATTACKER_WINS\b|\bdef\s+(attacker_won|wins_of|winner)\b"
)
WHO_WON_HOME = "league/core/payoff.py"


def who_won_copies(root: Path) -> list[str]:
    return [v for v in violations(root, WHO_WON, {WHO_WON_HOME}) if not v.startswith("envs/")]  # envs: the game's rules


def test_who_won_only_in_payoff():
    assert who_won_copies(ROOT) == []


def test_the_who_won_scan_finds_the_old_copies(tmp_path):
    root = plant(tmp_path, {
        WHO_WON_HOME: 'ATTACKER_WINS = frozenset(("captured", "timeout"))\n',
        "league/curves.py": 'wins = self.attacker_wins if side == "attacker" else self.games - self.attacker_wins\n',
        "league/exploit.py": 'wins = played.attacker_wins if side == "attacker" else played.games - played.attacker_wins\n',
        "league/analysis/generations.py": 'wins.append(attacker_wins if side == "attacker" else n - attacker_wins)\n',
        "league/replay.py": 'won = "attacker" if outcome.attacker_wins else "team"\n',
        "bench/league_quality.py": 'wins = attacker_wins if side == "attacker" else args.episodes - attacker_wins\n',
        "league/status.py": 'wins, games = record_against(payoff, side, player, opponent)\n',  # asks payoff: fine
        "envs/agents.py": "def attacker_wins(self):\n    return self in (CAPTURED, TIMEOUT)\n",  # the game's own rule
    })
    assert [v.split(":")[0] for v in who_won_copies(root)] == [
        "bench/league_quality.py", "league/analysis/generations.py", "league/curves.py", "league/exploit.py",
        "league/replay.py",
    ]


# ---------------------------------------------------------------- training rewards
# How a learner is paid in training, assembled by hand: the game's reward functions imported,
# an attacker's reward picked out of the env's three by its method, the win reward added, the
# team's rewards summed, a shaping potential or its distances, advantages by GAE's recursion.
TRAINING_REWARD = re.compile(
    r"\bfrom\s+envs\.rewards\b|\bimport\s+envs\.rewards\b|\bfrom\s+envs\s+import\b[^\n]*\brewards\b"
    r"|\[[^\]\n]*\bmethod\s*-\s*1\s*\]|\bwin_reward\s*\*"
    r"|rewards\[[\"']targeter[\"']\][^\n]*\+[^\n]*rewards\[[\"']defender[\"']\]"
    r"|\bpotential_shaping\b|\bSHAPED_DISTANCE\b|\b(terminal|interception)_distance\b|\bdef\s+gae\b"
)
TRAINING_REWARD_HOME = "league/rollout/"


def training_reward_copies(root: Path) -> list[str]:
    """Lines that assemble a training reward outside ``league/rollout/`` and ``envs/`` (the game's rules)."""
    return [v for v in violations(root, TRAINING_REWARD, set()) if not v.startswith(("envs/", TRAINING_REWARD_HOME))]


def test_training_rewards_only_in_the_rollout():
    assert training_reward_copies(ROOT) == []


def test_the_training_reward_scan_finds_the_old_assembly(tmp_path):
    # The lines as they stood in the RLlib adapter before `league/rollout/training_reward.py`.
    root = plant(tmp_path, {
        "league/rllib/env_runner.py":
            'SHAPED_DISTANCE = {"targeter": terminal_distance, "defender": interception_distance}\n'
            "rewards = rows.attacker_rewards[:t, :, method - 1]\n"
            "rewards = rewards + win_reward * np.where(attacker_won_games(rows.outcome[:t]), 1.0, -1.0) * ended\n"
            'rewards = rows.rewards["targeter"][:t] + rows.rewards["defender"][:t]\n'
            "rewards = rewards + potential_shaping(-shaping * distance, ended, gamma)\n",
        "league/rllib/callbacks.py": 'compat.overwrite_rewards(attacker, [info["attacker_rewards"][method - 1] for info in infos])\n',
        "league/rllib/modules.py": "from envs.rewards import attacker_method2\n",
        "league/training/coordinator.py": "from envs import agents, rewards\n",
        "bench/plain_ppo.py": "def gae(rewards, values):\n",
        "league/rollout/training_reward.py": "rewards = rewards + pay.attacker_win_reward * won * ended\n",  # its home
        "envs/core.py": "from envs import rewards\n",  # the game's own rules
        "league/rllib/bridge.py": "win_reward=run.ppo.win_reward(reward_method)\n",  # a setting passed on: fine
    })
    assert [":".join(v.split(":")[:2]) for v in training_reward_copies(root)] == [
        "bench/plain_ppo.py:1", "league/rllib/callbacks.py:1", "league/rllib/env_runner.py:1",
        "league/rllib/env_runner.py:2", "league/rllib/env_runner.py:3", "league/rllib/env_runner.py:4",
        "league/rllib/env_runner.py:5", "league/rllib/modules.py:1", "league/training/coordinator.py:1",
    ]


# ---------------------------------------------------------------- module settings
# RLlib's model_config dict read by key (a misspelt key would read as "off"), aliased to be read
# so, or written as a literal: only its parser may, the rest read `module.settings` by attribute.
MODEL_CONFIG_BY_KEY = re.compile(
    r"\bmodel_config\s*(\[|\.\s*\w+\(|or\b|=\s*(\{|dict\())"
    r"|=\s*[\w.\[\]\"']*\.model_config\s*(or\b|$)"
)
MODULE_SETTINGS_HOME = "league/rllib/module_settings.py"


def test_module_settings_are_read_only_through_their_type():
    assert violations(ROOT, MODEL_CONFIG_BY_KEY, {MODULE_SETTINGS_HOME}) == []


def test_the_module_settings_scan_finds_model_config_read_by_key(tmp_path):
    root = plant(tmp_path, {
        MODULE_SETTINGS_HOME: "given = {k: v for k, v in (model_config or {}).items()}\n",
        "league/rllib/env_runner.py": 'explores = module.model_config.get("explore_when_forzen", True)\n',
        "league/rllib/learner.py": 'bf16 = bool(self.module[m].model_config["bf16"])\n',
        "league/rllib/callbacks.py": 'method = (rl_module[module_id].model_config or {}).get("reward_method")\n',
        "league/rllib/modules.py": "cfg = self.model_config\nsettings = ActorCriticSettings.from_model_config(self.model_config)\n",
        "league/rllib/bridge.py": 'spec = RLModuleSpec(model_config={"agent": agent})\nspec = RLModuleSpec(model_config=s.as_model_config())\n',
        "bench/learner_update.py": 'learner.module[TEAM.name].model_config["bf16"] = arm == "bf16"\n',
        "league/config.py": "model_config = ConfigDict(extra=\"forbid\")\n",  # pydantic's own: fine
    })
    assert [":".join(v.split(":")[:2]) for v in violations(root, MODEL_CONFIG_BY_KEY, {MODULE_SETTINGS_HOME})] == [
        "bench/learner_update.py:1", "league/rllib/bridge.py:1", "league/rllib/callbacks.py:1",
        "league/rllib/env_runner.py:1", "league/rllib/learner.py:1", "league/rllib/modules.py:1",
    ]


# ---------------------------------------------------------------- the layout tables
LAYOUT_PATH = re.compile(r"`(league/[\w/]*(?:\.py|/))`")


def layout_table_paths(page: str) -> set[str]:
    """The ``league/`` paths named in the first cell of the rows of a page's "Layout" table."""
    section = page.split("\n## Layout\n", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("| ")]
    return {path for row in rows for path in LAYOUT_PATH.findall(row.split(" | ")[0])}


def tree_paths(root: Path, packages_only: bool = False) -> set[str]:
    """``league``'s modules and sub-packages (``league/core/``), as the layout tables name them;
    ``packages_only``: its sub-packages and its top-level modules (the README's table)."""
    paths = set()
    for path in (root / "league").rglob("*.py"):
        relative = path.relative_to(root).as_posix()
        top_level = path.parent == root / "league"
        if packages_only and not top_level:
            paths.add(path.parent.relative_to(root).as_posix() + "/")
            continue
        package = path.name == "__init__.py" and not top_level
        paths.add(relative.removesuffix("__init__.py") if package else relative)
    return paths


def test_the_readme_layout_table_lists_the_packages():
    assert layout_table_paths((ROOT / "README.md").read_text()) == tree_paths(ROOT, packages_only=True)


def test_the_architecture_layout_table_lists_every_module():
    assert layout_table_paths((ROOT / "docs" / "architecture.md").read_text()) == tree_paths(ROOT)


def test_the_layout_scan_finds_a_missing_and_a_stale_row(tmp_path):
    root = plant(tmp_path, {
        "league/__init__.py": "", "league/run.py": "", "league/core/__init__.py": "", "league/core/payoff.py": "",
        "league/core/pfsp.py": "",
        "README.md": "# x\n\n## Layout\n\n| path | what |\n| --- | --- |\n| `league/run.py` | trains |\n"
                     "| `league/__init__.py` | the package |\n| `league/core/` | decisions |\n| `league/core/payoff.py`, `league/payoff.py` | who won |\n"
                     "\n## Next\n\n`league/core/pfsp.py` in prose does not count\n",
    })
    listed, tree = layout_table_paths((root / "README.md").read_text()), tree_paths(root)
    assert tree - listed == {"league/core/pfsp.py"} and listed - tree == {"league/payoff.py"}
    assert tree_paths(root, packages_only=True) == {"league/__init__.py", "league/run.py", "league/core/"}


# Sizes a reader takes in at once (issue "The league decides, the coordinator executes").
MAX_CLASS_LINES = 250
MAX_PARAMETERS = 8  # not counting self or cls


def oversized(root: Path) -> list[str]:
    """``path:line: what`` of every class over ``MAX_CLASS_LINES`` lines and every function over
    ``MAX_PARAMETERS`` parameters in ``league/``."""
    found = []
    for path in sorted((root / "league").rglob("*.py")):
        relative = path.relative_to(root).as_posix()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef) and node.end_lineno - node.lineno + 1 > MAX_CLASS_LINES:
                found.append(f"{relative}:{node.lineno}: class {node.name}, {node.end_lineno - node.lineno + 1} lines")
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                args = node.args
                names = [a.arg for a in args.posonlyargs + args.args + args.kwonlyargs]
                count = len(names) - (names[:1] in (["self"], ["cls"]))
                if count > MAX_PARAMETERS:
                    found.append(f"{relative}:{node.lineno}: {node.name}, {count} parameters")
    return found


def test_no_class_over_250_lines_and_no_function_over_8_parameters():
    assert oversized(ROOT) == []


def test_the_size_scan_finds_a_long_class_and_a_long_signature(tmp_path):
    long_class = "class Big:\n" + "    x = 1\n" * MAX_CLASS_LINES
    method = "class Ok:\n    def f(self, a, b, c, d, e, f, g, h):\n        pass\n"  # self not counted: 8
    function = "def g(a, b, c, d, e, f, g, h, *, i):\n    pass\n"
    root = plant(tmp_path, {"league/big.py": long_class, "league/ok.py": method, "league/g.py": function})
    assert [line.split(": ", 1)[1] for line in oversized(root)] == ["class Big, 251 lines", "g, 9 parameters"]

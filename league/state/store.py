"""League state in SQLite (``league.db`` in the run directory): the single source of truth.

The coordinator writes one transaction per iteration holding that iteration's game
results, new players, ratings, counters and, when it checkpointed, the checkpoint
record; a kill mid-iteration therefore leaves the database at the previous iteration.
On resume, rows of iterations after the last checkpoint are deleted
(``rollback_after``), so nothing is counted twice. WAL mode lets ``league.status``
read while training writes.

The schema is written under a temporary name and renamed into place, so a reader never
sees a ``league.db`` without its tables. Opening an existing database checks it
(``PRAGMA quick_check`` and the tables) and raises ``DamagedStoreError`` naming the
file and the problem.

Schema versions: a new database gets ``SCHEMA`` whole and ``PRAGMA user_version`` set to
the number of the last of ``MIGRATIONS``; opening an older one applies the migrations
after its version, in order, in one transaction. Databases made before the version was
kept (``user_version`` 0, from the first schema on) get each migration whose change is
not there yet (``Migration.present``): their opening code used to add these changes in
whatever order it met them. ``tests/state/test_migrations.py`` opens a database of the
first schema and checks it ends with ``SCHEMA``'s tables, columns and indexes.
"""

from __future__ import annotations

import json
import os
import sqlite3
from contextlib import contextmanager
from pathlib import Path
from dataclasses import dataclass
from typing import Any, Callable, Iterator

from league.core.payoff import OutcomeCount
from league.core.players import NewPlayer, Player

DB_NAME = "league.db"

# Columns of one measurement on the fixed games (league.evaluation.learning_curves.GameStats): means per game of
# the per-step rewards, without any terminal reward (derived from the wins on read).
CURVE_STATS = (
    "games", "attacker_wins", "attacker_return_1", "attacker_return_2", "attacker_return_3",
    "targeter_return", "defender_return", "mean_steps",
)
CURVE_STATS_SQL = """games INTEGER NOT NULL,
    attacker_wins INTEGER NOT NULL,
    attacker_return_1 REAL NOT NULL,  -- A's reward under method 1 (Eq. 7), summed over the game
    attacker_return_2 REAL NOT NULL,  -- method 2 (Eq. 8)
    attacker_return_3 REAL NOT NULL,  -- method 3 (Eq. 9)
    targeter_return REAL NOT NULL,    -- Eq. 10
    defender_return REAL NOT NULL,    -- Eq. 11
    mean_steps REAL NOT NULL"""

SCHEMA = """
CREATE TABLE IF NOT EXISTS players (
    id INTEGER PRIMARY KEY,
    side TEXT NOT NULL,
    kind TEXT NOT NULL,
    version INTEGER NOT NULL,
    reward_method INTEGER,
    parent INTEGER REFERENCES players(id),
    scripted_attacker TEXT,
    scripted_targeter TEXT,
    scripted_defender TEXT,
    env_steps INTEGER NOT NULL DEFAULT 0,
    checkpoint TEXT,                 -- saved module directory, relative to the run directory
    created_iteration INTEGER NOT NULL,
    created_at TEXT NOT NULL DEFAULT (datetime('now')),
    seed INTEGER,                    -- a best response's training seed
    env_step_budget INTEGER,         -- a best response's training budget in env steps
    from_prior INTEGER               -- a best response: 1 started from the run's prior, 0 from scratch
);
-- games' outcomes by (attacker, team); the table keeps its first name so older databases open
CREATE TABLE IF NOT EXISTS matches (
    iteration INTEGER NOT NULL,
    source TEXT NOT NULL,            -- 'training', 'evaluation' (the dev games) or 'test' (the held-out test games)
    attacker INTEGER NOT NULL REFERENCES players(id),
    team INTEGER NOT NULL REFERENCES players(id),
    outcome TEXT NOT NULL,           -- an envs.agents.Outcome label
    count INTEGER NOT NULL
);
-- every iteration's ratings sum the outcomes per pair: read in order from this index, not sorted anew
CREATE INDEX IF NOT EXISTS matches_by_pair ON matches (attacker, team, outcome, source, iteration, count);
CREATE TABLE IF NOT EXISTS ratings (
    iteration INTEGER NOT NULL,
    player INTEGER NOT NULL REFERENCES players(id),
    rating REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS iterations (
    iteration INTEGER PRIMARY KEY,
    phase INTEGER NOT NULL,
    learner_side TEXT NOT NULL,
    env_steps INTEGER NOT NULL,      -- total so far
    episodes INTEGER NOT NULL,       -- total so far
    steps_per_second REAL NOT NULL,
    wall_seconds REAL NOT NULL,
    returns TEXT NOT NULL DEFAULT '{}'  -- mean episode return per learner module (JSON)
);
CREATE TABLE IF NOT EXISTS checkpoints (
    iteration INTEGER PRIMARY KEY,
    path TEXT NOT NULL,              -- relative to the run directory
    state TEXT NOT NULL,             -- the coordinator's RunState at this checkpoint (JSON)
    created_at TEXT NOT NULL DEFAULT (datetime('now'))
);
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
""" + """
CREATE TABLE IF NOT EXISTS curve_points (     -- learning curves: a learner on the fixed games as it trains
    iteration INTEGER NOT NULL,
    learner INTEGER NOT NULL REFERENCES players(id),
    opponent INTEGER NOT NULL REFERENCES players(id),
    env_steps INTEGER NOT NULL,      -- the learner's env steps when measured
    {stats}
);
CREATE TABLE IF NOT EXISTS curve_references (  -- learning curves: a reference player against a curve opponent
    iteration INTEGER NOT NULL,      -- when it was measured (once per run and opponent)
    opponent INTEGER NOT NULL REFERENCES players(id),
    side TEXT NOT NULL,              -- the side the reference plays (the learner's)
    kind TEXT NOT NULL,              -- 'scripted' or 'untrained' (a learner's version 0)
    name TEXT NOT NULL,              -- display name
    player INTEGER REFERENCES players(id),  -- the version-0 snapshot of an 'untrained' row
    {stats}
);
CREATE TABLE IF NOT EXISTS evaluation_stats (  -- a pair's newest evaluation: returns beside its wins
    iteration INTEGER NOT NULL,
    source TEXT NOT NULL,            -- as in matches: 'evaluation' (dev games) or 'test'
    attacker INTEGER NOT NULL REFERENCES players(id),
    team INTEGER NOT NULL REFERENCES players(id),
    {stats},
    outcomes BLOB                    -- each game's envs.agents.Outcome value (one byte a game, in game order)
);
""".format(stats=CURVE_STATS_SQL)

TABLES = ("players", "matches", "ratings", "iterations", "checkpoints", "meta")


def _columns(db: sqlite3.Connection, table: str) -> set[str]:
    return {row[1] for row in db.execute(f"PRAGMA table_info({table})")}


def _schema_objects(db: sqlite3.Connection, kind: str) -> set[str]:
    return {name for (name,) in db.execute("SELECT name FROM sqlite_master WHERE type = ?", (kind,))}


# The statements of a migration are as they were written: later schema changes are later migrations.
_FIRST_CURVE_STATS = (
    "games INTEGER NOT NULL, attacker_wins INTEGER NOT NULL, attacker_return_1 REAL NOT NULL, "
    "attacker_return_2 REAL NOT NULL, attacker_return_3 REAL NOT NULL, targeter_return REAL NOT NULL, "
    "defender_return REAL NOT NULL, mean_steps REAL NOT NULL"
)


@dataclass(frozen=True)
class Migration:
    """One change of the schema since the first one (``number`` 1, the ``TABLES``)."""

    number: int
    what: str
    sql: str
    present: Callable[[sqlite3.Connection], bool]  # whether a database of unknown version has it already


MIGRATIONS = (
    Migration(2, "iterations.returns",
              "ALTER TABLE iterations ADD COLUMN returns TEXT NOT NULL DEFAULT '{}';",
              lambda db: "returns" in _columns(db, "iterations")),
    Migration(3, "best responses' seed and budget",
              "ALTER TABLE players ADD COLUMN seed INTEGER; ALTER TABLE players ADD COLUMN env_step_budget INTEGER;",
              lambda db: {"seed", "env_step_budget"} <= _columns(db, "players")),
    Migration(4, "learning curves",
              "CREATE TABLE curve_points (iteration INTEGER NOT NULL, learner INTEGER NOT NULL REFERENCES players(id), "
              "opponent INTEGER NOT NULL REFERENCES players(id), env_steps INTEGER NOT NULL, "
              f"{_FIRST_CURVE_STATS}); "
              "CREATE TABLE curve_references (iteration INTEGER NOT NULL, opponent INTEGER NOT NULL REFERENCES players(id), "
              "side TEXT NOT NULL, kind TEXT NOT NULL, name TEXT NOT NULL, player INTEGER REFERENCES players(id), "
              f"{_FIRST_CURVE_STATS});",
              lambda db: {"curve_points", "curve_references"} <= _schema_objects(db, "table")),
    Migration(5, "the matches index by pair",
              "CREATE INDEX matches_by_pair ON matches (attacker, team, outcome, source, iteration, count);",
              lambda db: "matches_by_pair" in _schema_objects(db, "index")),
    Migration(6, "players.from_prior",
              "ALTER TABLE players ADD COLUMN from_prior INTEGER;",
              lambda db: "from_prior" in _columns(db, "players")),
    Migration(7, "evaluation_stats",
              "CREATE TABLE evaluation_stats (iteration INTEGER NOT NULL, source TEXT NOT NULL, "
              "attacker INTEGER NOT NULL REFERENCES players(id), team INTEGER NOT NULL REFERENCES players(id), "
              f"{_FIRST_CURVE_STATS});",
              lambda db: "evaluation_stats" in _schema_objects(db, "table")),
    Migration(8, "evaluation_stats.outcomes",
              "ALTER TABLE evaluation_stats ADD COLUMN outcomes BLOB;",
              lambda db: "outcomes" in _columns(db, "evaluation_stats")),
)
SCHEMA_VERSION = MIGRATIONS[-1].number  # ``SCHEMA``'s

# Columns that hold when something happened or how long it took: the only ones in which two
# runs of one config and seed may differ (``LeagueStore.contents``).
WALL_CLOCK_COLUMNS = {
    "players": ("created_at",),
    "iterations": ("steps_per_second", "wall_seconds"),
    "checkpoints": ("created_at",),
}

PLAYER_COLUMNS = (
    "id, side, kind, version, reward_method, parent, scripted_attacker, scripted_targeter, "
    "scripted_defender, env_steps, checkpoint, created_iteration, seed, env_step_budget, from_prior"
)
PLAYER_FIELDS = tuple(PLAYER_COLUMNS.split(", "))


class DamagedStoreError(ValueError):
    """A ``league.db`` that cannot be read as a league database; the message names the file."""


def create_database(path: Path) -> None:
    """Write an empty league database with its schema at ``path``, in one rename."""
    partial = path.with_name(path.name + ".partial")
    for stale in (partial, partial.with_name(partial.name + "-wal"), partial.with_name(partial.name + "-shm")):
        stale.unlink(missing_ok=True)
    db = sqlite3.connect(partial, isolation_level=None)
    try:
        db.execute("PRAGMA journal_mode=WAL")  # kept in the file: every later connection is in WAL mode
        db.executescript(f"BEGIN; {SCHEMA} PRAGMA user_version = {SCHEMA_VERSION}; COMMIT;")
    finally:
        db.close()  # the last connection folds the WAL into the file and removes it
    os.replace(partial, path)


class _MeasurementTables:
    """The tables of measurements on the fixed games: evaluations' returns and outcomes, learning curves."""

    db: sqlite3.Connection

    # ---------------------------------------------------------------- evaluations' returns and outcomes
    def record_evaluation_stats(
        self, iteration: int, source: str, attacker: int, team: int, stats: dict[str, float], outcomes: bytes | None = None
    ) -> None:
        """A pair's returns and wins on its fixed games (``CURVE_STATS`` columns) and each game's outcome,
        replacing the pair's earlier ones."""
        self.db.execute("DELETE FROM evaluation_stats WHERE source = ? AND attacker = ? AND team = ?", (source, attacker, team))
        self.db.execute(
            f"INSERT INTO evaluation_stats (iteration, source, attacker, team, {', '.join(CURVE_STATS)}, outcomes) "
            f"VALUES (?, ?, ?, ?, {', '.join('?' for _ in CURVE_STATS)}, ?)",
            (iteration, source, attacker, team, *[stats[c] for c in CURVE_STATS], outcomes),
        )

    def evaluation_outcomes(self, source: str = "evaluation") -> dict[tuple[int, int], bytes]:
        """``(attacker id, team id)`` -> each game's outcome byte of the pair's newest evaluation on ``source``'s games."""
        cursor = self.db.execute(
            "SELECT attacker, team, outcomes FROM evaluation_stats WHERE source = ? AND outcomes IS NOT NULL", (source,)
        )
        return {(a, t): outcomes for a, t, outcomes in cursor.fetchall()}

    def evaluation_stats(self, source: str = "evaluation") -> dict[tuple[int, int], dict[str, float]]:
        """``(attacker id, team id)`` -> the ``CURVE_STATS`` columns of the pair's newest evaluation on ``source``'s games."""
        cursor = self.db.execute(f"SELECT attacker, team, {', '.join(CURVE_STATS)} FROM evaluation_stats WHERE source = ?", (source,))
        return {(a, t): dict(zip(CURVE_STATS, values)) for a, t, *values in cursor.fetchall()}

    # ---------------------------------------------------------------- learning curves
    def record_curve_point(self, iteration: int, learner: int, opponent: int, env_steps: int, stats: dict[str, float]) -> None:
        """One learning-curve point; ``stats`` holds the ``CURVE_STATS`` columns."""
        values = [stats[c] for c in CURVE_STATS]
        self.db.execute(
            f"INSERT INTO curve_points (iteration, learner, opponent, env_steps, {', '.join(CURVE_STATS)}) "
            f"VALUES (?, ?, ?, ?, {', '.join('?' for _ in CURVE_STATS)})",
            (iteration, learner, opponent, env_steps, *values),
        )

    def record_curve_reference(
        self, iteration: int, opponent: int, side: str, kind: str, name: str, player: int | None, stats: dict[str, float]
    ) -> None:
        """One reference line: ``name`` (scripted, or the ``player`` at version 0) against ``opponent``."""
        values = [stats[c] for c in CURVE_STATS]
        self.db.execute(
            f"INSERT INTO curve_references (iteration, opponent, side, kind, name, player, {', '.join(CURVE_STATS)}) "
            f"VALUES (?, ?, ?, ?, ?, ?, {', '.join('?' for _ in CURVE_STATS)})",
            (iteration, opponent, side, kind, name, player, *values),
        )

    def curve_points(self) -> list[dict[str, Any]]:
        """Every learning-curve point (``curve_points`` columns), by learner, opponent and env steps."""
        cursor = self.db.execute("SELECT * FROM curve_points ORDER BY learner, opponent, env_steps, iteration")
        names = [c[0] for c in cursor.description]
        return [dict(zip(names, row)) for row in cursor.fetchall()]

    def curve_references(self) -> list[dict[str, Any]]:
        """Every reference row (``curve_references`` columns), by opponent."""
        cursor = self.db.execute("SELECT * FROM curve_references ORDER BY opponent, side, kind, name")
        names = [c[0] for c in cursor.description]
        return [dict(zip(names, row)) for row in cursor.fetchall()]


class LeagueStore(_MeasurementTables):
    def __init__(self, run_dir: Path, create: bool = False):
        path = Path(run_dir) / DB_NAME
        if create:
            create_database(path)
        elif not path.exists():
            raise FileNotFoundError(f"no league database at {path}")
        self.path = path
        try:
            self.db = sqlite3.connect(path, isolation_level=None, timeout=30.0)
        except sqlite3.DatabaseError as err:
            raise DamagedStoreError(f"{path} cannot be opened ({err})") from err
        try:
            self.check()
            self.db.execute("PRAGMA foreign_keys=ON")
            self.migrate()
        except sqlite3.DatabaseError as err:
            self.db.close()
            raise DamagedStoreError(f"{path} is damaged ({err})") from err
        except DamagedStoreError:
            self.db.close()
            raise

    def check(self) -> None:
        """Raise ``DamagedStoreError`` unless the file is an intact SQLite database with the league's tables."""
        (verdict,) = self.db.execute("PRAGMA quick_check(1)").fetchone()
        if verdict != "ok":
            raise DamagedStoreError(f"{self.path} is damaged (integrity check: {' '.join(verdict.split())})")
        tables = {name for (name,) in self.db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        missing = [t for t in TABLES if t not in tables]
        if missing:
            what = "empty" if not tables else "not a league database"
            raise DamagedStoreError(f"{self.path} is {what} (no table {', '.join(missing)})")

    def migrate(self) -> None:
        """Bring an older database to ``SCHEMA_VERSION`` (see the module docstring), in one transaction."""
        (version,) = self.db.execute("PRAGMA user_version").fetchone()
        if version > SCHEMA_VERSION:
            raise DamagedStoreError(f"{self.path} has schema version {version}, made by a newer version of the league "
                                    f"(this one reads up to {SCHEMA_VERSION})")
        if version == SCHEMA_VERSION:
            return
        with self.transaction():
            for migration in MIGRATIONS:
                if migration.number > version and not migration.present(self.db):
                    for statement in migration.sql.split(";"):
                        if statement.strip():
                            self.db.execute(statement)
            self.db.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")

    def backup(self, path: Path) -> None:
        """A consistent copy of the whole database at ``path`` (SQLite's online backup), in one rename."""
        partial = Path(path).with_name(Path(path).name + ".partial")
        partial.unlink(missing_ok=True)
        target = sqlite3.connect(partial)
        try:
            self.db.backup(target)
        finally:
            target.close()
        os.replace(partial, path)

    def integrity_check(self) -> str:
        """SQLite's full ``PRAGMA integrity_check``: ``"ok"``, or the problems found, one per line."""
        return "\n".join(row[0] for row in self.db.execute("PRAGMA integrity_check"))

    def close(self) -> None:
        self.db.close()

    @contextmanager
    def transaction(self) -> Iterator[None]:
        self.db.execute("BEGIN IMMEDIATE")
        try:
            yield
        except BaseException:
            self.db.execute("ROLLBACK")
            raise
        self.db.execute("COMMIT")

    def contents(self) -> dict[str, list[tuple]]:
        """Every table's rows, sorted, without ``WALL_CLOCK_COLUMNS``: what two runs of one
        config and seed have in common (all of it, for the fast and batched samplers)."""
        tables = [name for (name,) in self.db.execute("SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")]
        contents = {}
        for table in tables:
            columns = [row[1] for row in self.db.execute(f"PRAGMA table_info({table})")]
            kept = [c for c in columns if c not in WALL_CLOCK_COLUMNS.get(table, ())]
            listed = ", ".join(kept)
            contents[table] = self.db.execute(f"SELECT {listed} FROM {table} ORDER BY {listed}").fetchall()
        return contents

    # ---------------------------------------------------------------- meta
    def set_meta(self, key: str, value: Any) -> None:
        self.db.execute("INSERT OR REPLACE INTO meta VALUES (?, ?)", (key, json.dumps(value)))

    def get_meta(self, key: str, default: Any = None) -> Any:
        row = self.db.execute("SELECT value FROM meta WHERE key = ?", (key,)).fetchone()
        return json.loads(row[0]) if row else default

    # ---------------------------------------------------------------- players
    def add_player(self, iteration: int, player: NewPlayer) -> Player:
        """Record a new league member, created in ``iteration``; returns its row."""
        columns = player.columns()
        names = ", ".join(columns) + ", created_iteration"
        marks = ", ".join("?" for _ in range(len(columns) + 1))
        cursor = self.db.execute(f"INSERT INTO players ({names}) VALUES ({marks})", (*columns.values(), iteration))
        return self.player(cursor.lastrowid)

    def player(self, player_id: int) -> Player:
        row = self.db.execute(f"SELECT {PLAYER_COLUMNS} FROM players WHERE id = ?", (player_id,)).fetchone()
        if row is None:
            raise KeyError(f"no player with id {player_id}")
        return Player(**dict(zip(PLAYER_FIELDS, row)))

    def players(self, side: str | None = None, kind: str | None = None) -> list[Player]:
        rows = self.db.execute(
            f"SELECT {PLAYER_COLUMNS} FROM players WHERE (?1 IS NULL OR side = ?1) AND (?2 IS NULL OR kind = ?2) "
            "ORDER BY id",
            (side, kind),
        ).fetchall()
        return [Player(**dict(zip(PLAYER_FIELDS, row))) for row in rows]

    def set_player_steps(self, player_id: int, env_steps: int) -> None:
        self.db.execute("UPDATE players SET env_steps = ? WHERE id = ?", (env_steps, player_id))

    # ---------------------------------------------------------------- results
    def record_outcomes(self, iteration: int, source: str, rows: list[OutcomeCount]) -> None:
        self.db.executemany(
            "INSERT INTO matches VALUES (?, ?, ?, ?, ?, ?)",
            [(iteration, source, r.attacker, r.team, r.outcome, r.count) for r in rows],
        )

    def record_evaluation(self, iteration: int, rows: list[OutcomeCount], source: str = "evaluation") -> None:
        """Record evaluation results on the dev games (``source`` ``evaluation``) or the test
        games (``test``: only final tables and studies read them), replacing repeats of a pair.

        The same fixed games played again are not new evidence, so a pair's evaluation is one
        measurement: the newest. Between two frozen players it replaces every earlier one; a
        pair with a learner (whose weights change between iterations) replaces only its
        evaluation of this iteration, and its earlier ones stay as the learner's history.
        """
        for attacker, team in {(r.attacker, r.team) for r in rows}:
            self.db.execute(
                "DELETE FROM matches WHERE source = ?4 AND attacker = ?1 AND team = ?2 AND (iteration = ?3 "
                "OR NOT EXISTS (SELECT 1 FROM players WHERE id IN (?1, ?2) AND kind = 'learner'))",
                (attacker, team, iteration, source),
            )
        self.record_outcomes(iteration, source, rows)

    def newest_evaluation_rows(self, source: str = "evaluation") -> list[OutcomeCount]:
        """The outcomes of each pair's newest evaluation on the dev games (or ``source`` ``test``)."""
        return self._outcome_counts(
            "SELECT m.attacker, m.team, m.outcome, SUM(m.count) FROM matches m JOIN ("
            "  SELECT attacker, team, MAX(iteration) AS newest FROM matches WHERE source = ?1 "
            "  GROUP BY attacker, team"
            ") n ON m.attacker = n.attacker AND m.team = n.team AND m.iteration = n.newest "
            "WHERE m.source = ?1 GROUP BY m.attacker, m.team, m.outcome",
            (source,),
        )

    def counted_results(self, source: str | None = None) -> list[OutcomeCount]:
        """Outcomes with every game counted once: the training
        episodes and each pair's newest evaluation (``source`` picks one of the two)."""
        training = self.outcome_rows("training") if source in (None, "training") else []
        return training + (self.newest_evaluation_rows() if source in (None, "evaluation") else [])

    def training_rows_by_iteration(self) -> list[tuple[int, OutcomeCount]]:
        """``(iteration, outcomes)`` of the training episodes, oldest first."""
        rows = self.db.execute(
            "SELECT iteration, attacker, team, outcome, SUM(count) FROM matches WHERE source = 'training' "
            "GROUP BY iteration, attacker, team, outcome ORDER BY iteration"
        ).fetchall()
        return [(iteration, OutcomeCount(*counts)) for iteration, *counts in rows]

    def outcome_rows(self, source: str | None = None, since_iteration: int = 0) -> list[OutcomeCount]:
        """Outcomes of ``source``'s games (every source: evaluations repeated count again) since ``since_iteration``."""
        return self._outcome_counts(
            "SELECT attacker, team, outcome, SUM(count) FROM matches "
            "WHERE (?1 IS NULL OR source = ?1) AND iteration >= ?2 GROUP BY attacker, team, outcome",
            (source, since_iteration),
        )

    def _outcome_counts(self, query: str, parameters: tuple = ()) -> list[OutcomeCount]:
        """``OutcomeCount`` rows of a query selecting attacker, team, outcome and a count."""
        return [OutcomeCount(*row) for row in self.db.execute(query, parameters).fetchall()]

    def record_ratings(self, iteration: int, ratings: dict[int, float]) -> None:
        self.db.executemany("INSERT INTO ratings VALUES (?, ?, ?)", [(iteration, p, r) for p, r in ratings.items()])

    def replace_ratings(self, iteration: int, ratings: dict[int, float]) -> None:
        """The ratings of ``iteration``, refitted (after an evaluation added results)."""
        self.db.execute("DELETE FROM ratings WHERE iteration = ?", (iteration,))
        self.record_ratings(iteration, ratings)

    def rating_history(self) -> list[tuple[int, int, float]]:
        """``(iteration, player, rating)``, oldest first."""
        return self.db.execute("SELECT iteration, player, rating FROM ratings ORDER BY iteration, player").fetchall()

    def latest_ratings(self) -> dict[int, float]:
        rows = self.db.execute(
            "SELECT player, rating FROM ratings WHERE iteration = (SELECT MAX(iteration) FROM ratings)"
        ).fetchall()
        return dict(rows)

    def record_iteration(self, iteration: int, **columns: Any) -> None:
        names = ", ".join(columns)
        marks = ", ".join("?" for _ in columns)
        self.db.execute(f"INSERT INTO iterations (iteration, {names}) VALUES (?, {marks})", (iteration, *columns.values()))

    def last_iteration(self) -> dict[str, Any] | None:
        cursor = self.db.execute("SELECT * FROM iterations ORDER BY iteration DESC LIMIT 1")
        row = cursor.fetchone()
        return dict(zip([c[0] for c in cursor.description], row)) if row else None

    def iteration_rows(self) -> list[dict[str, Any]]:
        """Every recorded iteration (``iterations`` columns), oldest first."""
        cursor = self.db.execute("SELECT * FROM iterations ORDER BY iteration")
        names = [c[0] for c in cursor.description]
        return [dict(zip(names, row)) for row in cursor.fetchall()]

    def training_seconds(self) -> float:
        """Wall time of all recorded training iterations."""
        return self.db.execute("SELECT COALESCE(SUM(wall_seconds), 0) FROM iterations").fetchone()[0]

    def iteration_count(self) -> int:
        return self.db.execute("SELECT COUNT(*) FROM iterations").fetchone()[0]

    # ---------------------------------------------------------------- checkpoints
    def record_checkpoint(self, iteration: int, path: str, state: str) -> None:
        self.db.execute(
            "INSERT OR REPLACE INTO checkpoints (iteration, path, state) VALUES (?, ?, ?)", (iteration, path, state)
        )

    def checkpoints(self) -> list[tuple[int, str]]:
        return self.db.execute("SELECT iteration, path FROM checkpoints ORDER BY iteration").fetchall()

    def last_checkpoint(self) -> tuple[int, str, dict[str, Any]] | None:
        row = self.db.execute("SELECT iteration, path, state FROM checkpoints ORDER BY iteration DESC LIMIT 1").fetchone()
        return (row[0], row[1], json.loads(row[2])) if row else None

    def rollback_after(self, iteration: int) -> None:
        """Forget everything written after ``iteration`` (work a resume will redo)."""
        with self.transaction():
            for table in ("matches", "ratings", "curve_points", "curve_references", "evaluation_stats"):
                self.db.execute(f"DELETE FROM {table} WHERE iteration > ?", (iteration,))
            self.db.execute("DELETE FROM iterations WHERE iteration > ?", (iteration,))
            self.db.execute("DELETE FROM checkpoints WHERE iteration > ?", (iteration,))
            self.db.execute("DELETE FROM players WHERE created_iteration > ?", (iteration,))
            if (self.get_meta("evaluated_iteration") or 0) > iteration:  # its evaluation rows are gone
                self.db.execute("DELETE FROM meta WHERE key = 'evaluated_iteration'")

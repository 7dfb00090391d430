"""Numbered store migrations: a database of the first schema, and one that earlier code
changed out of order, open as ``SCHEMA``'s; one of a newer version is refused."""

import sqlite3

import pytest

from league.core.players import NewPlayer
from league.state.store import DB_NAME, SCHEMA_VERSION, DamagedStoreError, LeagueStore, create_database

# league.db's schema at the first commit (8949265, league/store.py), as such files still hold it.
FIRST_SCHEMA = """
CREATE TABLE players (
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
    checkpoint TEXT,
    created_iteration INTEGER NOT NULL,
    created_at TEXT NOT NULL DEFAULT (datetime('now'))
);
CREATE TABLE matches (
    iteration INTEGER NOT NULL,
    source TEXT NOT NULL,
    attacker INTEGER NOT NULL REFERENCES players(id),
    team INTEGER NOT NULL REFERENCES players(id),
    outcome TEXT NOT NULL,
    count INTEGER NOT NULL
);
CREATE TABLE ratings (
    iteration INTEGER NOT NULL,
    player INTEGER NOT NULL REFERENCES players(id),
    rating REAL NOT NULL
);
CREATE TABLE iterations (
    iteration INTEGER PRIMARY KEY,
    phase INTEGER NOT NULL,
    learner_side TEXT NOT NULL,
    env_steps INTEGER NOT NULL,
    episodes INTEGER NOT NULL,
    steps_per_second REAL NOT NULL,
    wall_seconds REAL NOT NULL
);
CREATE TABLE checkpoints (
    iteration INTEGER PRIMARY KEY,
    path TEXT NOT NULL,
    state TEXT NOT NULL,
    created_at TEXT NOT NULL DEFAULT (datetime('now'))
);
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
"""


def schema(path) -> dict:
    """Every table's columns (name, type, not null, default, key) and foreign keys, and every index's columns."""
    db = sqlite3.connect(path)
    try:
        objects = db.execute("SELECT type, name, tbl_name FROM sqlite_master WHERE name NOT LIKE 'sqlite_%'").fetchall()
        found = {}
        for kind, name, table in objects:
            if kind == "table":
                found[name] = ([row[1:] for row in db.execute(f"PRAGMA table_info({name})")],
                               [row[2:5] for row in db.execute(f"PRAGMA foreign_key_list({name})")])
            else:
                found[f"{kind} {name}"] = (table, [row[2] for row in db.execute(f"PRAGMA index_info({name})")])
        return found
    finally:
        db.close()


def user_version(path) -> int:
    db = sqlite3.connect(path)
    try:
        return db.execute("PRAGMA user_version").fetchone()[0]
    finally:
        db.close()


def old_database(run_dir, statements: str) -> None:
    db = sqlite3.connect(run_dir / DB_NAME)
    db.executescript(statements)
    db.close()


@pytest.fixture
def fresh(tmp_path):
    (tmp_path / "fresh").mkdir()
    create_database(tmp_path / "fresh" / DB_NAME)
    return schema(tmp_path / "fresh" / DB_NAME)


def test_a_database_of_the_first_schema_opens_migrated_with_its_rows(tmp_path, fresh):
    old_database(tmp_path, FIRST_SCHEMA + """
        INSERT INTO players (side, kind, version, reward_method, created_iteration) VALUES ('attacker', 'learner', 0, 2, 0);
        INSERT INTO players (side, kind, version, scripted_attacker, created_iteration) VALUES ('attacker', 'scripted', 0, 'lead_intercept', 0);
        INSERT INTO players (side, kind, version, created_iteration) VALUES ('team', 'snapshot', 1, 3);
        INSERT INTO matches VALUES (3, 'training', 1, 3, 'attacker_captured_targeter', 7);
        INSERT INTO iterations VALUES (3, 0, 'attacker', 1000, 40, 500.0, 2.0);
        INSERT INTO checkpoints (iteration, path, state) VALUES (3, 'checkpoints/iter_000003', '{}');
    """)
    assert user_version(tmp_path / DB_NAME) == 0
    store = LeagueStore(tmp_path)
    try:
        assert [p.name for p in store.players()] == ["attacker-m2", "scripted-lead_intercept", "team-v1"]
        assert store.last_iteration()["returns"] == "{}"  # migration 2's default for the old row
        assert store.outcome_rows("training")[0].count == 7
        with store.transaction():  # what each migration added can be written
            br = store.add_player(3, NewPlayer("attacker", "best_response", 0, 2, seed=4, env_step_budget=9, from_prior=True))
            store.record_curve_point(3, 1, 3, 100, dict.fromkeys(("games", "attacker_wins"), 1) | {
                k: 0.5 for k in ("attacker_return_1", "attacker_return_2", "attacker_return_3",
                                 "targeter_return", "defender_return", "mean_steps")})
            store.record_evaluation_stats(3, "evaluation", br.id, 3, store.curve_points()[0], outcomes=b"\x01")
        assert (br.seed, br.env_step_budget, br.from_prior) == (4, 9, 1)
        assert store.evaluation_outcomes() == {(br.id, 3): b"\x01"}
    finally:
        store.close()
    assert user_version(tmp_path / DB_NAME) == SCHEMA_VERSION
    assert schema(tmp_path / DB_NAME) == fresh


def test_a_database_changed_out_of_order_by_earlier_code_gets_only_what_it_lacks(tmp_path, fresh):
    # Earlier opening code added from_prior to a database whose curve tables it found, without the matches index.
    old_database(tmp_path, FIRST_SCHEMA + """
        ALTER TABLE iterations ADD COLUMN returns TEXT NOT NULL DEFAULT '{}';
        ALTER TABLE players ADD COLUMN seed INTEGER;
        ALTER TABLE players ADD COLUMN env_step_budget INTEGER;
        ALTER TABLE players ADD COLUMN from_prior INTEGER;
    """)
    LeagueStore(tmp_path).close()
    assert schema(tmp_path / DB_NAME) == fresh
    assert user_version(tmp_path / DB_NAME) == SCHEMA_VERSION


def test_a_new_database_is_at_the_last_version_and_opening_it_changes_nothing(tmp_path, fresh):
    create_database(tmp_path / DB_NAME)
    assert user_version(tmp_path / DB_NAME) == SCHEMA_VERSION
    before = (tmp_path / DB_NAME).stat().st_mtime_ns
    LeagueStore(tmp_path).close()
    assert (tmp_path / DB_NAME).stat().st_mtime_ns == before


def test_a_database_of_a_newer_version_is_refused_naming_both_versions(tmp_path):
    create_database(tmp_path / DB_NAME)
    old_database(tmp_path, f"PRAGMA user_version = {SCHEMA_VERSION + 1};")
    with pytest.raises(DamagedStoreError, match=f"schema version {SCHEMA_VERSION + 1}.*up to {SCHEMA_VERSION}"):
        LeagueStore(tmp_path)

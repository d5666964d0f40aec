"""The metadata store: one SQLite file in the data directory (stdlib sqlite3).

Why plain sqlite3 and not SQLAlchemy: three small tables, a handful of
queries, and the atomic state changes of the job lease are clearest as
explicit SQL in ``BEGIN IMMEDIATE`` transactions. WAL mode lets the API read
while workers (other processes) write; ``busy_timeout`` makes writers queue
instead of failing. A connection is opened per unit of work, so any thread
or process may use the store.
"""
from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

SCHEMA = """
CREATE TABLE IF NOT EXISTS sets (
    id TEXT PRIMARY KEY,
    name TEXT NOT NULL,
    source TEXT NOT NULL,            -- 'images' (detection runs) or 'observations' (uploaded corners)
    board TEXT,                      -- JSON board spec, or NULL
    image_size TEXT,                 -- JSON [width, height] once known
    coverage TEXT,                   -- JSON from detection
    warnings TEXT NOT NULL DEFAULT '[]',
    n_views INTEGER NOT NULL DEFAULT 0,
    created_at REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS images (
    set_id TEXT NOT NULL REFERENCES sets(id) ON DELETE CASCADE,
    idx INTEGER NOT NULL,
    name TEXT NOT NULL,
    status TEXT NOT NULL,            -- pending | used | rejected
    n_corners INTEGER,
    reason TEXT,
    sharpness REAL,
    width INTEGER,
    height INTEGER,
    PRIMARY KEY (set_id, name)
);
CREATE TABLE IF NOT EXISTS jobs (
    id TEXT PRIMARY KEY,
    kind TEXT NOT NULL,              -- 'detect' (a set's corners), 'calibrate' or 'rig' (several sets, set_id NULL)
    set_id TEXT,
    method TEXT,
    settings TEXT NOT NULL DEFAULT '{}',
    state TEXT NOT NULL,             -- queued | running | done | failed | cancelled
    stage TEXT,
    progress REAL NOT NULL DEFAULT 0,
    error TEXT,
    attempts INTEGER NOT NULL DEFAULT 0,
    cancel_requested INTEGER NOT NULL DEFAULT 0,
    worker TEXT,
    heartbeat_at REAL,
    created_at REAL NOT NULL,
    started_at REAL,
    finished_at REAL,
    stages TEXT NOT NULL DEFAULT '{}', -- JSON {stage: seconds}
    artefacts TEXT NOT NULL DEFAULT '[]',
    summary TEXT NOT NULL DEFAULT '{}'
);
CREATE INDEX IF NOT EXISTS jobs_state ON jobs(state);
CREATE INDEX IF NOT EXISTS jobs_set ON jobs(set_id);
CREATE TABLE IF NOT EXISTS workers (
    id TEXT PRIMARY KEY,
    host TEXT NOT NULL,
    pid INTEGER NOT NULL,
    started_at REAL NOT NULL,
    heartbeat_at REAL NOT NULL
);
"""


class Database:
    """Opens short-lived connections to one SQLite file; creates the schema once."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with self.connect() as con:
            con.execute("PRAGMA journal_mode=WAL")
            con.executescript(SCHEMA)
        # Held open, never used: SQLite checkpoints and deletes the WAL when the *last* connection
        # closes, so with a connection per unit of work a status read could pay for a checkpoint
        # (an fsync of the database, seconds on a busy disk). With this one open, checkpoints
        # happen only inside writers' commits, and reads stay cheap.
        # It reads once, so that it has the WAL open: that also keeps the -shm file that readers need when
        # the data directory turns read-only (SQLite cannot create it then, and every read would fail).
        self._keeper = sqlite3.connect(self.path, check_same_thread=False)
        self._keeper.execute("SELECT 1 FROM sqlite_master LIMIT 1").fetchall()

    @contextmanager
    def connect(self) -> Iterator[sqlite3.Connection]:
        con = sqlite3.connect(self.path, timeout=30.0, isolation_level=None)
        con.row_factory = sqlite3.Row
        con.execute("PRAGMA foreign_keys=ON")
        con.execute("PRAGMA busy_timeout=30000")
        try:
            yield con
        finally:
            con.close()

    @contextmanager
    def transaction(self) -> Iterator[sqlite3.Connection]:
        """A write transaction that takes the lock at once (no upgrade deadlocks)."""
        with self.connect() as con:
            con.execute("BEGIN IMMEDIATE")
            try:
                yield con
            except BaseException:
                con.execute("ROLLBACK")
                raise
            con.execute("COMMIT")


def dumps(value: Any) -> str:
    return json.dumps(value, separators=(",", ":"))


def loads(text: str | None, default: Any = None) -> Any:
    return default if text is None else json.loads(text)

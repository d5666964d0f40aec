"""Worker processes announce themselves with a heartbeat; /api/health counts the live ones."""
from __future__ import annotations

import time

from ..db import Database


def beat(db: Database, worker_id: str, host: str, pid: int, started_at: float, within_seconds: float) -> None:
    """This worker is alive; workers silent for ten leases are forgotten (written here, not on reads)."""
    now = time.time()
    with db.transaction() as con:
        con.execute("DELETE FROM workers WHERE heartbeat_at < ?", (now - 10 * within_seconds,))
        con.execute(
            "INSERT INTO workers (id, host, pid, started_at, heartbeat_at) VALUES (?,?,?,?,?) "
            "ON CONFLICT(id) DO UPDATE SET heartbeat_at=excluded.heartbeat_at",
            (worker_id, host, pid, started_at, now))


def remove(db: Database, worker_id: str) -> None:
    with db.transaction() as con:
        con.execute("DELETE FROM workers WHERE id = ?", (worker_id,))


def live(db: Database, within_seconds: float) -> list[str]:
    """Workers heard from recently (a pure read: health works on a read-only data directory)."""
    with db.connect() as con:
        rows = con.execute("SELECT id FROM workers WHERE heartbeat_at >= ? ORDER BY id",
                           (time.time() - within_seconds,)).fetchall()
    return [r["id"] for r in rows]

"""Worker processes announce themselves with a heartbeat; /api/health counts the live ones."""
from __future__ import annotations

import time

from ..db import Database


def beat(db: Database, worker_id: str, host: str, pid: int, started_at: float) -> None:
    with db.transaction() as con:
        con.execute(
            "INSERT INTO workers (id, host, pid, started_at, heartbeat_at) VALUES (?,?,?,?,?) "
            "ON CONFLICT(id) DO UPDATE SET heartbeat_at=excluded.heartbeat_at",
            (worker_id, host, pid, started_at, time.time()))


def remove(db: Database, worker_id: str) -> None:
    with db.transaction() as con:
        con.execute("DELETE FROM workers WHERE id = ?", (worker_id,))


def live(db: Database, within_seconds: float) -> list[str]:
    """Workers heard from recently; forgets the long-silent ones."""
    now = time.time()
    with db.transaction() as con:
        con.execute("DELETE FROM workers WHERE heartbeat_at < ?", (now - 10 * within_seconds,))
        rows = con.execute("SELECT id FROM workers WHERE heartbeat_at >= ? ORDER BY id",
                           (now - within_seconds,)).fetchall()
    return [r["id"] for r in rows]

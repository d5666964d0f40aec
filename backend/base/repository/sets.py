"""Image sets and their images' detection reports."""
from __future__ import annotations

import time
from typing import Any

from ..db import Database, dumps, loads


class Full(Exception):
    """The database already holds as many sets as it may (``create``'s ``limit``)."""

    def __init__(self, held: int):
        super().__init__(f"{held} sets held")
        self.held = held


def create(db: Database, set_id: str, name: str, source: str, board: dict | None,
           image_names: list[str], image_size: list[int] | None = None, n_views: int = 0,
           limit: int | None = None) -> None:
    """Insert the set and its images; raises Full when ``limit`` sets are already held, counted
    inside the write transaction, so that uploads finishing together cannot pass it."""
    with db.transaction() as con:
        if limit is not None and (held := int(con.execute("SELECT COUNT(*) FROM sets").fetchone()[0])) >= limit:
            raise Full(held)
        con.execute(
            "INSERT INTO sets (id, name, source, board, image_size, n_views, created_at) VALUES (?,?,?,?,?,?,?)",
            (set_id, name, source, None if board is None else dumps(board),
             None if image_size is None else dumps(image_size), n_views, time.time()),
        )
        con.executemany(
            "INSERT INTO images (set_id, idx, name, status) VALUES (?,?,?, 'pending')",
            [(set_id, i, n) for i, n in enumerate(image_names)],
        )


def _decode(row) -> dict[str, Any]:
    d = dict(row)
    d["board"] = loads(d["board"])
    d["image_size"] = loads(d["image_size"])
    d["coverage"] = loads(d["coverage"])
    d["warnings"] = loads(d["warnings"], [])
    return d


def get(db: Database, set_id: str) -> dict[str, Any] | None:
    with db.connect() as con:
        row = con.execute("SELECT * FROM sets WHERE id = ?", (set_id,)).fetchone()
        if row is None:
            return None
        d = _decode(row)
        d["images"] = [dict(r) for r in con.execute(
            "SELECT name, status, n_corners, reason, sharpness, width, height FROM images "
            "WHERE set_id = ? ORDER BY idx", (set_id,))]
    return d


def list_all(db: Database) -> list[dict[str, Any]]:
    with db.connect() as con:
        rows = con.execute(
            "SELECT s.*, (SELECT COUNT(*) FROM images i WHERE i.set_id = s.id) AS n_images "
            "FROM sets s ORDER BY created_at DESC").fetchall()
    return [_decode(r) for r in rows]


def count(db: Database) -> int:
    with db.connect() as con:
        return int(con.execute("SELECT COUNT(*) FROM sets").fetchone()[0])


def record_reports(db: Database, set_id: str, reports: list[dict[str, Any]]) -> None:
    """Store detection reports as they become known (one call per batch of images)."""
    with db.transaction() as con:
        con.executemany(
            "UPDATE images SET status=?, n_corners=?, reason=?, sharpness=?, width=?, height=? "
            "WHERE set_id=? AND name=?",
            [(r["status"], r.get("n_corners"), r.get("reason"), r.get("sharpness"), r.get("width"),
              r.get("height"), set_id, r["name"]) for r in reports],
        )


def record_detection(db: Database, set_id: str, image_size: list[int] | None, coverage: dict | None,
                     warnings: list[str], n_views: int) -> None:
    with db.transaction() as con:
        con.execute("UPDATE sets SET image_size=?, coverage=?, warnings=?, n_views=? WHERE id=?",
                    (None if image_size is None else dumps(image_size),
                     None if coverage is None else dumps(coverage), dumps(warnings), n_views, set_id))


def set_board(db: Database, set_id: str, board: dict) -> None:
    """The board the set's photos are detected with (a new detection follows)."""
    with db.transaction() as con:
        con.execute("UPDATE sets SET board=?, n_views=0, warnings='[]', coverage=NULL WHERE id=?",
                    (dumps(board), set_id))


def reset_images(db: Database, set_id: str) -> None:
    """Back to 'pending' before a detection is retried."""
    with db.transaction() as con:
        con.execute("UPDATE images SET status='pending', n_corners=NULL, reason=NULL WHERE set_id=?", (set_id,))


def delete(db: Database, set_id: str) -> None:
    with db.transaction() as con:
        con.execute("DELETE FROM jobs WHERE set_id = ?", (set_id,))
        con.execute("DELETE FROM sets WHERE id = ?", (set_id,))

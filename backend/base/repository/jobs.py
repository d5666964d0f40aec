"""Jobs and their lease: every state change is one conditional UPDATE.

A run is identified by ``(id, attempts)``: a worker that lost its lease (its
job was re-queued after it fell silent) matches no row any more, so it can
neither overwrite progress nor finish a job another worker now owns.
"""
from __future__ import annotations

import time
from typing import Any

from ..db import Database, dumps, loads

ACTIVE = ("queued", "running")


WAITING_FOR_DETECTION = "waiting for detection"  # the stage of a calibration queued on a set still detecting
EXCLUDE_KEY = "exclude_views"  # in a calibration's stored settings: the views left out of it (JobCreate.exclude)
RIG_KEY = "rig"  # in a rig job's stored settings: its cameras (set_ids, names, reference, hold_models)


def split_settings(settings: dict[str, Any]) -> tuple[dict[str, Any], list[str]]:
    """A calibration's stored settings → (the method's settings, the names of the views left out)."""
    rest = dict(settings)
    return rest, list(rest.pop(EXCLUDE_KEY, []))


def split_rig(settings: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any] | None]:
    """A job's stored settings → (the method's settings, the rig's cameras or None for other kinds)."""
    rest = dict(settings)
    return rest, rest.pop(RIG_KEY, None)


def create(db: Database, job_id: str, kind: str, set_id: str | None, method: str | None,
           settings: dict[str, Any], stage: str = "queued") -> None:
    with db.transaction() as con:
        con.execute(
            "INSERT INTO jobs (id, kind, set_id, method, settings, state, stage, created_at) "
            "VALUES (?,?,?,?,?, 'queued', ?, ?)",
            (job_id, kind, set_id, method, dumps(settings), stage, time.time()))


def _decode(row) -> dict[str, Any]:
    d = dict(row)
    for key, default in (("settings", {}), ("stages", {}), ("artefacts", []), ("summary", {})):
        d[key] = loads(d[key], default)
    d["cancel_requested"] = bool(d["cancel_requested"])
    return d


def get(db: Database, job_id: str) -> dict[str, Any] | None:
    with db.connect() as con:
        row = con.execute("SELECT * FROM jobs WHERE id = ?", (job_id,)).fetchone()
    return None if row is None else _decode(row)


def list_all(db: Database, kind: str | None = None, set_id: str | None = None,
             state: str | None = None) -> list[dict[str, Any]]:
    sql, args = "SELECT * FROM jobs WHERE 1=1", []
    for col, val in (("kind", kind), ("set_id", set_id), ("state", state)):
        if val is not None:
            sql += f" AND {col} = ?"
            args.append(val)
    with db.connect() as con:
        rows = con.execute(sql + " ORDER BY created_at DESC", args).fetchall()
    return [_decode(r) for r in rows]


def latest_detection(db: Database, set_id: str) -> dict[str, Any] | None:
    with db.connect() as con:
        row = con.execute("SELECT * FROM jobs WHERE kind='detect' AND set_id=? ORDER BY created_at DESC LIMIT 1",
                          (set_id,)).fetchone()
    return None if row is None else _decode(row)


def queued_on_set(db: Database, set_id: str) -> list[str]:
    """Ids of the queued calibrations of a set, oldest first (those a finished detection releases)."""
    with db.connect() as con:
        rows = con.execute("SELECT id FROM jobs WHERE kind='calibrate' AND set_id=? AND state='queued' "
                           "ORDER BY created_at", (set_id,)).fetchall()
    return [r["id"] for r in rows]


def fail_queued(db: Database, job_id: str, error: str) -> bool:
    """queued → failed with ``error`` (a calibration whose set's detection failed); False if no longer queued."""
    with db.transaction() as con:
        cur = con.execute("UPDATE jobs SET state='failed', stage='failed', error=?, finished_at=? "
                          "WHERE id=? AND state='queued'", (error, time.time(), job_id))
    return cur.rowcount == 1


def claim(db: Database, job_id: str, worker: str) -> int | None:
    """queued → running for this worker; the attempt number, or None if not claimable."""
    now = time.time()
    with db.transaction() as con:
        row = con.execute("SELECT state, cancel_requested, attempts FROM jobs WHERE id=?", (job_id,)).fetchone()
        if row is None or row["state"] != "queued":
            return None
        if row["cancel_requested"]:
            con.execute("UPDATE jobs SET state='cancelled', stage='cancelled', finished_at=? WHERE id=?",
                        (now, job_id))
            return None
        attempt = row["attempts"] + 1
        con.execute(
            "UPDATE jobs SET state='running', attempts=?, worker=?, heartbeat_at=?, "
            "started_at=COALESCE(started_at, ?), error=NULL, stages='{}', "
            "stage=CASE stage WHEN ? THEN 'queued' ELSE stage END WHERE id=?",
            (attempt, worker, now, now, WAITING_FOR_DETECTION, job_id))
    return attempt


def heartbeat(db: Database, job_id: str, attempt: int) -> bool:
    """Extend the lease; False when this run no longer owns the job."""
    with db.transaction() as con:
        cur = con.execute("UPDATE jobs SET heartbeat_at=? WHERE id=? AND attempts=? AND state='running'",
                          (time.time(), job_id, attempt))
    return cur.rowcount == 1


def report(db: Database, job_id: str, attempt: int, stage: str, progress: float,
           stages: dict[str, float]) -> tuple[bool, bool]:
    """Store progress; returns (still owned, cancel requested)."""
    with db.transaction() as con:
        cur = con.execute(
            "UPDATE jobs SET stage=?, progress=?, stages=?, heartbeat_at=? "
            "WHERE id=? AND attempts=? AND state='running'",
            (stage, progress, dumps(stages), time.time(), job_id, attempt))
        row = con.execute("SELECT cancel_requested FROM jobs WHERE id=?", (job_id,)).fetchone()
    return cur.rowcount == 1, bool(row and row["cancel_requested"])


def finish(db: Database, job_id: str, attempt: int, state: str, error: str | None = None,
           artefacts: list[str] | None = None, summary: dict[str, Any] | None = None,
           stages: dict[str, float] | None = None) -> bool:
    """running → done | failed | cancelled, only by the run that owns the job."""
    sets = ["state=?", "error=?", "finished_at=?", "stage=?"]
    args: list[Any] = [state, error, time.time(), state]
    if state == "done":
        sets.append("progress=100")
    for col, val in (("artefacts", artefacts), ("summary", summary), ("stages", stages)):
        if val is not None:
            sets.append(f"{col}=?")
            args.append(dumps(val))
    with db.transaction() as con:
        cur = con.execute(f"UPDATE jobs SET {', '.join(sets)} WHERE id=? AND attempts=? AND state='running'",
                          (*args, job_id, attempt))
    return cur.rowcount == 1


def request_cancel(db: Database, job_id: str) -> str | None:
    """Cancel a queued job at once; ask a running one to stop. The state after, or None if absent."""
    with db.transaction() as con:
        row = con.execute("SELECT state FROM jobs WHERE id=?", (job_id,)).fetchone()
        if row is None:
            return None
        if row["state"] == "queued":
            con.execute("UPDATE jobs SET state='cancelled', stage='cancelled', cancel_requested=1, finished_at=? "
                        "WHERE id=?", (time.time(), job_id))
            return "cancelled"
        if row["state"] == "running":
            con.execute("UPDATE jobs SET cancel_requested=1 WHERE id=?", (job_id,))
        return row["state"]


def delete(db: Database, job_id: str) -> None:
    with db.transaction() as con:
        con.execute("DELETE FROM jobs WHERE id=?", (job_id,))


def stale(db: Database, lease_seconds: float) -> list[dict[str, Any]]:
    """Running jobs whose worker has been silent longer than the lease."""
    with db.connect() as con:
        rows = con.execute("SELECT * FROM jobs WHERE state='running' AND heartbeat_at < ?",
                           (time.time() - lease_seconds,)).fetchall()
    return [_decode(r) for r in rows]


def requeue_or_fail(db: Database, job_id: str, attempt: int, max_attempts: int, reason: str) -> str | None:
    """A dead run: back to 'queued' if attempts remain, else 'failed' with ``reason``."""
    with db.transaction() as con:
        row = con.execute("SELECT state, attempts, cancel_requested FROM jobs WHERE id=?", (job_id,)).fetchone()
        if row is None or row["state"] != "running" or row["attempts"] != attempt:
            return None
        if row["cancel_requested"]:
            new, error = "cancelled", None
        elif attempt < max_attempts:
            new, error = "queued", None
        else:
            new, error = "failed", f"{reason}; gave up after {attempt} attempt(s)"
        con.execute("UPDATE jobs SET state=?, stage=?, error=?, worker=NULL, finished_at=? WHERE id=?",
                    (new, new, error, None if new == "queued" else time.time(), job_id))
    return new


def queued_ids(db: Database) -> list[tuple[str, str]]:
    """(id, kind) of every queued job, oldest first."""
    with db.connect() as con:
        rows = con.execute("SELECT id, kind FROM jobs WHERE state='queued' ORDER BY created_at").fetchall()
    return [(r["id"], r["kind"]) for r in rows]


def count_by_state(db: Database) -> dict[str, int]:
    with db.connect() as con:
        rows = con.execute("SELECT state, COUNT(*) AS n FROM jobs GROUP BY state").fetchall()
    return {r["state"]: r["n"] for r in rows}


def waiting(db: Database, longer_than: float, lease_seconds: float) -> list[str]:
    """Ids of queued jobs waiting longer than ``longer_than`` seconds, oldest first.

    A job re-queued after its worker fell silent has waited since at least its last heartbeat
    plus the lease (when recovery could first take it back), not since it was created.
    A calibration waiting for its set's detection is not waiting for a worker: it is left out.
    """
    with db.connect() as con:
        rows = con.execute(
            "SELECT id FROM jobs j WHERE state='queued' AND MAX(created_at, COALESCE(heartbeat_at + ?, 0)) < ? "
            "AND NOT (kind='calibrate' AND EXISTS (SELECT 1 FROM jobs d WHERE d.kind='detect' "
            "AND d.set_id=j.set_id AND d.state IN ('queued', 'running'))) "
            "ORDER BY created_at", (lease_seconds, time.time() - longer_than)).fetchall()
    return [r["id"] for r in rows]

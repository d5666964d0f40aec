"""The job lease on a real SQLite file: claims, stale runs, retries and failures."""
from __future__ import annotations

import time

from backend.base.db import Database
from backend.base.repository import jobs


def make(tmp_path, job_id="j1") -> Database:
    db = Database(tmp_path / "freecal.db")
    jobs.create(db, job_id, "calibrate", None, "bspline", {})
    return db


def test_one_claim_wins_and_a_stale_run_cannot_write(tmp_path):
    db = make(tmp_path)
    assert jobs.claim(db, "j1", "w1") == 1
    assert jobs.claim(db, "j1", "w2") is None            # a duplicate queue message does nothing
    assert jobs.requeue_or_fail(db, "j1", 1, 2, "silent") == "queued"
    assert jobs.claim(db, "j1", "w2") == 2
    assert jobs.report(db, "j1", 1, "knots", 10, {}) == (False, False)   # the first run lost its lease
    assert not jobs.finish(db, "j1", 1, "done")
    assert jobs.finish(db, "j1", 2, "done")
    assert jobs.get(db, "j1")["state"] == "done"


def test_silent_job_fails_with_the_reason_after_its_last_attempt(tmp_path):
    db = make(tmp_path)
    jobs.claim(db, "j1", "w1")
    with db.transaction() as con:
        con.execute("UPDATE jobs SET heartbeat_at = ?", (time.time() - 100,))
    assert [j["id"] for j in jobs.stale(db, 10)] == ["j1"]
    assert jobs.requeue_or_fail(db, "j1", 1, 1, "worker w1 went silent") == "failed"
    job = jobs.get(db, "j1")
    assert job["state"] == "failed" and "worker w1 went silent" in job["error"] and job["finished_at"]
    assert jobs.stale(db, 10) == []


def test_cancel_queued_at_once_and_running_on_request(tmp_path):
    db = make(tmp_path)
    jobs.create(db, "j2", "calibrate", None, "bspline", {})
    assert jobs.request_cancel(db, "j1") == "cancelled"
    assert jobs.claim(db, "j1", "w1") is None
    assert jobs.claim(db, "j2", "w1") == 1
    assert jobs.request_cancel(db, "j2") == "running"
    assert jobs.report(db, "j2", 1, "knots", 10, {}) == (True, True)
    assert jobs.request_cancel(db, "nope") is None

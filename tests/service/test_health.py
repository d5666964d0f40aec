"""/api/health says "degraded", with what is wrong and what to do: workers missing, a stuck queue,
a data directory that takes no writes. And the worker supervisor of `freecal serve` on its own."""
from __future__ import annotations

import sys
import time

import pytest
from fastapi.testclient import TestClient

from backend.app.main import create_app
from backend.app.services import health as assessment
from backend.base.repository import jobs, workers
from backend.base.settings import Settings
from backend.queue import supervisor
from backend.queue.recovery import resend_stuck
from backend.queue.supervisor import Supervisor


@pytest.fixture
def app(tmp_path):
    settings = Settings.from_env(env={}, data_dir=tmp_path / "data", viewer=False, lease_seconds=5.0, workers=1)
    with TestClient(create_app(settings), base_url="http://127.0.0.1") as c:
        yield c


def beat(client: TestClient, worker_id: str = "host:1") -> None:
    ctx = client.app.state.ctx
    workers.beat(ctx.db, worker_id, "host", 1, time.time(), ctx.settings.lease_seconds)


def age(client: TestClient, job_id: str, seconds: float) -> None:
    with client.app.state.ctx.db.transaction() as con:
        con.execute("UPDATE jobs SET created_at = created_at - ? WHERE id = ?", (seconds, job_id))


def test_no_live_worker_is_degraded_and_says_what_to_do(app):
    h = app.get("/api/health").json()
    assert h["status"] == "degraded" and h["workers"] == 0 and h["workers_expected"] == 1
    assert "0 of the 1 worker(s)" in h["problems"][0] and "freecal worker" in h["problems"][0]
    beat(app)
    h = app.get("/api/health").json()
    assert h["status"] == "ok" and h["problems"] == [] and h["workers"] == 1 and h["storage_writable"]


def test_a_job_waiting_while_a_worker_idles_is_a_stuck_queue_and_is_sent_again(app, monkeypatch):
    ctx = app.app.state.ctx
    beat(app)
    jobs.create(ctx.db, "j1", "calibrate", None, "bspline", {})
    assert app.get("/api/health").json()["status"] == "ok"  # just queued: waiting is normal
    age(app, "j1", 6.0)
    h = app.get("/api/health").json()
    assert h["status"] == "degraded" and "1 job(s) have waited more than 5 s while a worker is idle" in h["problems"][0]
    sent = []
    monkeypatch.setattr(app.app.state.queue, "enqueue", sent.append)
    memo: dict[str, float] = {}
    assert resend_stuck(ctx, app.app.state.queue, memo) == 1 and sent == ["j1"]
    assert resend_stuck(ctx, app.app.state.queue, memo) == 0  # once per lease, not on every tick
    # a worker busy with another job: the wait is normal again
    jobs.create(ctx.db, "j2", "calibrate", None, "bspline", {})
    jobs.claim(ctx.db, "j2", "host:1")
    assert app.get("/api/health").json()["status"] == "ok"


def test_queued_jobs_and_no_worker_at_all(tmp_path):
    settings = Settings.from_env(env={}, data_dir=tmp_path / "data", viewer=False, lease_seconds=5.0, workers=0)
    with TestClient(create_app(settings), base_url="http://127.0.0.1") as c:
        assert c.get("/api/health").json()["status"] == "ok"  # workers run elsewhere, nothing waits
        jobs.create(c.app.state.ctx.db, "j1", "calibrate", None, "bspline", {})
        age(c, "j1", 6.0)
        h = c.get("/api/health").json()
        assert h["status"] == "degraded" and "no worker is running" in h["problems"][0]


def test_unwritable_data_directory_is_degraded_and_reads_still_answer(app, monkeypatch):
    import errno
    import os

    beat(app)
    real = os.open

    def full(path, flags, *args):
        if str(path).endswith(f".health-probe-{os.getpid()}"):
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(path, flags, *args)

    monkeypatch.setattr(assessment.os, "open", full)
    assessment._probes.clear()
    h = app.get("/api/health").json()
    assert h["status"] == "degraded" and not h["storage_writable"]
    assert "is full" in h["problems"][0] and "Reads and downloads work" in h["problems"][0]
    assessment._probes.clear()


# ---- the supervisor -----------------------------------------------------------------------
def test_supervisor_starts_a_dead_worker_again_and_pauses_for_one_that_keeps_dying(monkeypatch):
    monkeypatch.setattr(supervisor, "CHECK_SECONDS", 0.05)
    monkeypatch.setattr(supervisor, "FIRST_PAUSE_SECONDS", 0.2)
    sup = Supervisor([sys.executable, "-c", "raise SystemExit(3)"], {}, 1)
    sup.start()
    try:
        deadline = time.monotonic() + 30
        while sup.slots[0].restarts < 3 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert sup.slots[0].restarts >= 3, "a dead worker must be started again"
        assert sup.slots[0].pause >= 0.4, "a worker dying at once is started again after a growing pause"
    finally:
        sup.stop()
    assert not sup.is_alive()


def test_supervisor_stops_its_workers(monkeypatch):
    sup = Supervisor([sys.executable, "-c", "import time; time.sleep(600)"], {}, 2)
    sup.start()
    procs = [s.proc for s in sup.slots]
    assert len(sup.pids()) == 2
    sup.stop()
    assert all(p.poll() is not None for p in procs)

"""Faults: a full disk, an unwritable data directory, Redis going away and coming
back, the server killed outright, a job that runs past its time limit (one stuck
in C, never calling its progress callback: test_job_timeout.py).

What exists elsewhere and is not repeated here: a worker SIGKILLed mid-job is
retried and done by the next worker (test_service.py), the server killed mid-job
fails the run with the reason after its last attempt (test_service.py), and an
unreachable Redis at job creation answers 503 (test_service_redis.py). Supervision
(kill -9 of `freecal serve`'s worker, of a job process, of the server alone, a
stuck detection) is in test_supervision.py; a really full and a really read-only
data directory under the real server in test_storage_faults.py.

The in-process cases here make the file writes themselves raise ENOSPC / EROFS at
the point where the service really writes (byte-exact: the first image fits, the
second does not).
"""
from __future__ import annotations

import errno
import json
import shutil
import sqlite3
import subprocess

import pytest
from fastapi.testclient import TestClient

from backend.app.main import create_app
from backend.base import storage
from backend.base.repository import jobs as job_rows
from backend.base.settings import Settings

from ..conftest import synthetic
from .harness import (
    FAST,
    QUICK,
    Proc,
    RedisServer,
    Service,
    create_job,
    freecal,
    start_worker,
    upload_observations,
    wait_for,
    wait_job,
)
from .test_hardening_inputs import GOOD, still_works

OBS = synthetic("radial").train.to_json()


def fail_writes(monkeypatch, code: int, after: int = 0) -> None:
    """Every file write fails with ``code`` once ``after`` bytes in all were written: the disk filling up."""
    written = [0]
    enter = storage._atomic.__enter__

    class FailingFile:
        def __init__(self, f):
            self.f = f

        def write(self, data: bytes) -> int:
            if written[0] + len(data) > after:
                raise OSError(code, errno.errorcode[code])
            written[0] += len(data)
            return self.f.write(data)

        def __getattr__(self, name):
            return getattr(self.f, name)

    monkeypatch.setattr(storage._atomic, "__enter__", lambda self: FailingFile(enter(self)))


@pytest.fixture
def app(tmp_path):
    settings = Settings.from_env(env={}, data_dir=tmp_path / "data", viewer=False)
    with TestClient(create_app(settings), base_url="http://127.0.0.1") as c:  # a name the Host check allows
        yield c


def intact(client: TestClient) -> None:
    """Nothing half-written: no temp files, no set folder without its row, a sound database."""
    ctx = client.app.state.ctx
    assert not list(ctx.settings.data_dir.rglob(".tmp-*"))
    rows = {s["id"] for s in client.get("/api/sets").json()["sets"]}
    assert {p.name for p in (ctx.settings.data_dir / "sets").iterdir()} == rows
    with sqlite3.connect(ctx.settings.db_path) as con:
        assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"


def three_images() -> list:
    return [("files", (f"{k}.png", GOOD)) for k in range(3)]


@pytest.mark.parametrize("code, status, words", [
    (errno.ENOSPC, 507, ["disk is full", "nothing was stored", "free space"]),
    (errno.EROFS, 503, ["cannot write its data directory", "nothing was stored", "FREECAL_DATA_DIR"]),
    (errno.EACCES, 503, ["cannot write its data directory"]),
])
def test_upload_when_the_disk_fails_stores_nothing_and_says_why(app, monkeypatch, code, status, words):
    fail_writes(monkeypatch, code, after=len(GOOD))  # the first image fits, the second does not
    r = app.post("/api/sets", data={"board": "chessboard:6x4:20mm"}, files=three_images())
    assert r.status_code == status, r.text
    assert all(w in r.json()["detail"] for w in words), r.json()
    intact(app)
    monkeypatch.undo()  # space freed: the same upload now works
    assert app.post("/api/sets", data={"board": "chessboard:6x4:20mm"}, files=three_images()).status_code == 201
    intact(app)


def test_database_full_rolls_back_the_set(app, monkeypatch):
    from backend.base.repository import sets as set_rows

    def full(*args, **kwargs):
        raise sqlite3.OperationalError("database or disk is full")

    monkeypatch.setattr(set_rows, "create", full)
    r = app.post("/api/sets", files={"files": ("obs.json", json.dumps(OBS))})
    assert r.status_code == 507 and "disk is full" in r.json()["detail"]
    intact(app)


def test_job_whose_results_cannot_be_written_fails_with_the_reason(app, monkeypatch):
    from backend.queue.execute import run_claimed

    r = app.post("/api/jobs", json={"observations": OBS, "method": "bspline", "settings": QUICK})
    job_id = r.json()["id"]
    fail_writes(monkeypatch, errno.ENOSPC)
    ctx = app.app.state.ctx
    run_claimed(ctx, job_id, job_rows.claim(ctx.db, job_id, "test"))  # what the job process runs, here in-process
    job = app.get(f"/api/jobs/{job_id}").json()
    assert job["state"] == "failed" and "disk is full" in job["error"] and "could not be written" in job["error"]
    assert not job["downloads"]
    intact(app)


def test_unwritable_data_directory_is_one_clear_line(tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    for command in ("serve", "worker"):
        out = subprocess.run(freecal(command, "--data-dir", str(blocker / "data")), capture_output=True, text=True,
                             timeout=60)
        assert out.returncode == 2, out.stderr
        assert "cannot be written" in out.stderr and "--data-dir" in out.stderr and "Traceback" not in out.stderr


# ---- real processes ----------------------------------------------------------------------
def restart_redis(redis: RedisServer, log_dir) -> None:
    """Start redis-server again on the same port (what a restarted Redis looks like to clients)."""
    exe = shutil.which("redis-server")
    redis.proc = Proc("redis-again", [exe, "--port", str(redis.port), "--bind", "127.0.0.1", "--save", "",
                                      "--appendonly", "no", "--dir", str(log_dir)], log_dir)
    wait_for(redis._ping, 20, "redis-server to answer PING again", [redis.proc])


@pytest.mark.slow
def test_redis_goes_away_and_comes_back(tmp_path):
    redis = RedisServer(tmp_path)
    env = {**FAST, "FREECAL_QUEUE": "redis", "FREECAL_REDIS_URL": redis.url, "FREECAL_VIEWER": "0"}
    svc = Service(tmp_path / "data", tmp_path, env, workers=0)
    worker = None
    try:
        svc.start()
        worker = start_worker(svc.data_dir, tmp_path, env, "worker")
        logs = svc.logs() + [worker, redis.proc]
        set_id = upload_observations(svc.client, OBS)
        assert wait_job(svc.client, create_job(svc.client, set_id, settings=QUICK), 60, logs)["state"] == "done"

        redis.stop()
        health = svc.client.get("/api/health").json()
        assert health["queue_available"] is False and "unreachable" in health["queue_error"]
        r = svc.client.post("/api/jobs", json={"set_id": set_id, "method": "bspline", "settings": QUICK})
        assert r.status_code == 503 and "check that it is running and retry" in r.json()["detail"]
        assert svc.client.get(f"/api/sets/{set_id}").json()["state"] == "ready"  # reads still work
        jobs_before = svc.client.get("/api/jobs").json()["count"]
        assert jobs_before == 1, "a refused job must not be stored"

        restart_redis(redis, tmp_path)
        wait_for(lambda: svc.client.get("/api/health").json()["queue_available"], 30, "the API to see Redis again",
                 logs)
        job = wait_job(svc.client, create_job(svc.client, set_id, settings=QUICK), 90, logs + [redis.proc])
        assert job["state"] == "done", job["error"]
        assert worker.alive(), "the worker must ride out the outage"
    finally:
        if worker is not None:
            worker.stop()
        svc.stop()
        redis.stop()


@pytest.fixture(scope="module")
def timed(tmp_path_factory):
    root = tmp_path_factory.mktemp("faults")
    # FREECAL_WORKER_NICE=0: jobs yield the CPU to all other work, so on a busy shared machine a quick job
    # could pass the short limit; here the limit is under test, not the priority
    svc = Service(root / "data", root, {**FAST, "FREECAL_JOB_TIMEOUT": "4", "FREECAL_VIEWER": "0",
                                        "FREECAL_WORKER_NICE": "0"}).start()
    yield svc
    svc.stop()


@pytest.mark.slow
def test_server_killed_outright_keeps_sets_jobs_and_results(timed):
    c = timed.client
    set_id = upload_observations(c, OBS)
    job_id = create_job(c, set_id, settings=QUICK)
    assert wait_job(c, job_id, 60, timed.logs())["state"] == "done"
    result = c.get(f"/api/jobs/{job_id}/calibration.json").content
    timed.proc.kill()  # SIGKILL the server and its worker: no shutdown code runs
    timed.start()
    c = timed.client
    assert c.get(f"/api/sets/{set_id}").json()["state"] == "ready"
    assert c.get(f"/api/jobs/{job_id}").json()["state"] == "done"
    assert c.get(f"/api/jobs/{job_id}/calibration.json").content == result
    with sqlite3.connect(timed.data_dir / "freecal.db") as con:
        assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    assert wait_job(c, create_job(c, set_id, settings=QUICK), 60, timed.logs())["state"] == "done"


@pytest.mark.slow
def test_job_past_its_time_limit_is_failed_with_the_reason(timed):
    c = timed.client
    set_id = upload_observations(c, OBS)
    # every method, cross-validated: far longer than the 4 s limit
    job = wait_job(c, create_job(c, set_id, "compare", {"splits": 5}), 60, timed.logs())
    assert job["state"] == "failed", job
    assert "exceeded the 4 s time limit" in job["error"] and "FREECAL_JOB_TIMEOUT" in job["error"]
    assert not job["downloads"]
    # the worker is free again: the next job runs
    assert wait_job(c, create_job(c, set_id, settings=QUICK), 60, timed.logs())["state"] == "done"
    still_works(timed)

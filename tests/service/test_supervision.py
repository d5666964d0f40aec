"""Supervision: kill -9 of a worker, of a job process, of the server alone, with real processes.

Each ends with every job done or failed with a reason, no process of the dead
one left running, and /api/health "ok" again without a hand. A stuck detection
is made by test-only code in a ``sitecustomize`` module on PYTHONPATH (every
Python process of the service imports it, pool processes included): the first
detection's pool processes call libc's ``sleep`` through ``ctypes.PyDLL``, which
holds the GIL, so only a kill from outside ends them.
"""
from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from ..conftest import synthetic
from .harness import FAST, SLOW, Service, create_job, upload_observations, wait_for, wait_job
from .test_hardening_inputs import GOOD

pytestmark = pytest.mark.slow

OBS = synthetic("radial").train.to_json()
# FAST heartbeats, but a lease long enough that a loaded 2-core machine never makes a live run look
# dead (a new worker's first job waits for its fork server to import the job code): only the kills
# here end runs
ENV = {**FAST, "FREECAL_LEASE_SECONDS": "10", "FREECAL_VIEWER": "0"}

HOOK = '''
import ctypes, importlib.util, os, sys
from pathlib import Path


def _patch(module):
    real = module.detect_file
    marks = Path(os.environ["FREECAL_TEST_HANG_DIR"])

    def detect_file(path, board, name=None, model=None):
        if not (marks / "released").exists():  # detections hang until the test releases them
            (marks / f"pool-{os.getpid()}.pid").write_text(str(os.getpid()))
            ctypes.PyDLL(None).sleep(3600)
        return real(path, board, name, model)

    detect_file.__qualname__ = real.__qualname__  # pickled by name into the pool: must look like the real one
    module.detect_file = detect_file


class _PatchOnImport:
    # patched where the detector is imported, so other processes start as fast as ever
    def find_spec(self, name, path=None, target=None):
        if name != "calib_core.detection.detect_image":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        run = spec.loader.exec_module
        spec.loader.exec_module = lambda module: (run(module), _patch(module))
        return spec


if os.environ.get("FREECAL_TEST_HANG_DIR"):
    sys.meta_path.insert(0, _PatchOnImport())
'''


def gone(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return True
    return state == "Z"  # a zombie runs nothing: it only waits for its parent to reap it


def descendants(pid: int) -> set[int]:
    """Every process started (directly or not) by ``pid``, from /proc."""
    parents: dict[int, int] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            parents[int(stat.parent.name)] = int(stat.read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
    out, todo = set(), [pid]
    while todo:
        p = todo.pop()
        kids = {c for c, pp in parents.items() if pp == p} - out
        out |= kids
        todo += kids
    return out


def worker_pid(job: dict) -> int:
    return int(job["worker"].rsplit(":", 1)[1])


def healthy_again(svc: Service, workers: int = 1) -> dict:
    def check():
        h = svc.client.get("/api/health").json()
        return h if h["status"] == "ok" and h["workers"] == workers else None

    return wait_for(check, 60, "/api/health to be ok again", svc.logs())


@pytest.fixture
def service(tmp_path):
    svc = Service(tmp_path / "data", tmp_path, ENV).start()
    yield svc
    svc.stop()


def test_killed_worker_is_replaced_and_its_job_runs_again(service):
    c = service.client
    set_id = upload_observations(c, OBS)
    job_id = create_job(c, set_id, settings=SLOW)
    job = wait_job(c, job_id, 60, service.logs(), states=("running",))
    first = worker_pid(job)
    left = descendants(first)   # its fork server and the job's process
    assert left, "the worker runs its job in a child process"
    os.kill(first, signal.SIGKILL)
    wait_for(lambda: all(gone(p) for p in left), 30, f"the dead worker's processes {left} to end", service.logs())
    job = wait_job(c, job_id, 120, service.logs())
    assert job["state"] == "done", job["error"]
    assert job["attempts"] == 2 and worker_pid(job) != first
    health = healthy_again(service)
    assert health["problems"] == [] and health["workers_expected"] == 1


def test_killed_job_process_fails_its_job_with_the_reason_and_the_worker_goes_on(service):
    c = service.client
    set_id = upload_observations(c, OBS)
    job_id = create_job(c, set_id, settings={**SLOW, "max_iterations": 500})
    worker = worker_pid(wait_job(c, job_id, 60, service.logs(), states=("running",)))
    # worker → its fork server → the job's process
    pid = wait_for(lambda: next((p for p in descendants(worker) if parent(p) != worker), None), 30,
                   "the job's process", service.logs())
    os.kill(pid, signal.SIGKILL)
    job = wait_job(c, job_id, 60, service.logs())
    assert job["state"] == "failed" and "ended unexpectedly (killed by signal 9" in job["error"], job
    assert "retry" in job["error"]
    done = wait_job(c, create_job(c, set_id, settings=SLOW), 120, service.logs())
    assert done["state"] == "done" and worker_pid(done) == worker, done
    healthy_again(service)


def parent(pid: int) -> int | None:
    try:
        return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
    except (OSError, IndexError, ValueError):
        return None


def test_server_killed_alone_takes_its_workers_and_jobs_with_it(tmp_path):
    """SIGKILL of the `freecal serve` process only (not its group): the kernel ends its worker and the
    worker's job process; started again, the job runs again and is done."""
    svc = Service(tmp_path / "data", tmp_path, ENV).start()
    try:
        c = svc.client
        set_id = upload_observations(c, OBS)
        job_id = create_job(c, set_id, settings=SLOW)
        job = wait_job(c, job_id, 60, svc.logs(), states=("running",))
        left = descendants(svc.proc.pid)
        assert worker_pid(job) in left
        os.kill(svc.proc.pid, signal.SIGKILL)
        svc.proc.proc.wait(timeout=10)
        wait_for(lambda: all(gone(p) for p in left), 30, f"the server's processes {left} to end", svc.logs())
        svc.start()
        job = wait_job(svc.client, job_id, 120, svc.logs())
        assert job["state"] == "done" and job["attempts"] == 2, job
        healthy_again(svc)
    finally:
        svc.stop()


def test_worker_killed_during_a_stuck_detection_leaves_nothing_running(tmp_path):
    """The issue's case: a detection stuck in C, its worker killed. Its job process and the detection's
    pool processes end with it; the new worker runs the detection again once it can."""
    hook = tmp_path / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(HOOK)
    path = os.pathsep.join(p for p in (str(hook), os.environ.get("PYTHONPATH", "")) if p)
    env = {**ENV, "PYTHONPATH": path, "FREECAL_TEST_HANG_DIR": str(tmp_path)}
    svc = Service(tmp_path / "data", tmp_path, env).start()
    try:
        c = svc.client
        r = c.post("/api/sets", data={"board": "chessboard:6x4:20mm"},
                   files=[("files", (f"{k}.png", GOOD)) for k in range(3)])
        assert r.status_code == 201, r.text
        set_id = r.json()["id"]
        stuck = wait_for(lambda: [int(p.read_text()) for p in tmp_path.glob("pool-*.pid")], 60,
                         "the detection to hang in its pool", svc.logs())
        job = c.get(f"/api/jobs/{c.get(f'/api/sets/{set_id}').json()['detection_job']}").json()
        assert job["kind"] == "detect" and job["state"] == "running" and job["attempts"] == 1, job
        worker = worker_pid(job)
        left = descendants(worker)
        assert set(stuck) <= left
        (tmp_path / "released").write_text("")  # the next run detects for real
        os.kill(worker, signal.SIGKILL)
        wait_for(lambda: all(gone(p) for p in left), 30, f"the stuck detection's processes {left} to end",
                 svc.logs())
        s = wait_for(lambda: (lambda s: s if s["state"] in ("ready", "failed") else None)(
            c.get(f"/api/sets/{set_id}").json()), 120, "the detection to run again", svc.logs())
        assert s["state"] == "ready", (s["error"], s["images"])
        healthy_again(svc)
    finally:
        svc.stop()


def test_stuck_detection_is_stopped_at_the_time_limit(tmp_path):
    """Detections have the time limit too: the job process and its pool are killed, the set fails saying so."""
    hook = tmp_path / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(HOOK)
    path = os.pathsep.join(p for p in (str(hook), os.environ.get("PYTHONPATH", "")) if p)
    env = {**ENV, "FREECAL_JOB_TIMEOUT": "5", "PYTHONPATH": path, "FREECAL_TEST_HANG_DIR": str(tmp_path)}
    svc = Service(tmp_path / "data", tmp_path, env).start()
    try:
        c = svc.client
        r = c.post("/api/sets", data={"board": "chessboard:6x4:20mm"},
                   files=[("files", (f"{k}.png", GOOD)) for k in range(3)])
        set_id = r.json()["id"]
        stuck = wait_for(lambda: [int(p.read_text()) for p in tmp_path.glob("pool-*.pid")], 60,
                         "the detection to hang in its pool", svc.logs())
        s = wait_for(lambda: (lambda s: s if s["state"] in ("ready", "failed") else None)(
            c.get(f"/api/sets/{set_id}").json()), 60, "the detection to be stopped", svc.logs())
        assert s["state"] == "failed" and "exceeded the 5 s time limit" in s["error"], s
        wait_for(lambda: all(gone(p) for p in stuck), 30, f"the stuck pool processes {stuck} to end", svc.logs())
        healthy_again(svc)
    finally:
        svc.stop()

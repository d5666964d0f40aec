"""Each job runs in a process of its own, so its worker can always end it.

A solver stuck in C, or a loop that never calls its progress callback, cannot
be stopped from inside its own process (nothing Python-level runs there again).
So the worker thread that claimed a job starts a job process and keeps the
lease from outside (``supervise``), every ``FREECAL_HEARTBEAT_SECONDS``:

- heartbeat: the job looks alive to recovery exactly while its process runs;
- past ``FREECAL_JOB_TIMEOUT``: the process and everything it started (a
  detection's process pool) are killed and the job fails saying so;
- cancel requested, and the process did not stop by itself within one more
  heartbeat: killed, the job is cancelled;
- lease lost (recovery gave the job to another worker): killed, nothing written;
- the process died (out of memory, a crash in C): the job fails saying so.

Job processes come from a fork server (a fresh interpreter that imported the
job code once): a job starts in milliseconds and never inherits the worker's
threads or locks. On Linux a job process also dies with the fork server, which
ends with its worker, so a worker killed outright leaves no job running alone
(``calib_core.lifetime``). A job process runs in a session of its own at the
workers' niceness, as batch work (``_yield_to_the_api``), so the API answers fast
while it runs.
"""
from __future__ import annotations

import logging
import math
import multiprocessing as mp
import os
import signal
import threading
import time
from pathlib import Path

from ..base.context import Context
from ..base.repository import jobs
from ..base.settings import Settings

log = logging.getLogger("freecal.worker")
TIME_LIMIT = ("the job exceeded the {limit:g} s time limit (FREECAL_JOB_TIMEOUT) and was stopped: try fewer views "
              "or a fixed knot grid (knots: uniform, fewer intervals), or ask the administrator for a longer limit")
_live: set[mp.process.BaseProcess] = set()   # running job processes of this worker (stop_all)
_lock = threading.Lock()
_stopping = threading.Event()   # the worker is stopping now: the jobs it kills are retried, not failed


def supervise(ctx: Context, job_id: str, attempt: int) -> None:
    """Run the claimed job in a job process; return once it ended, one way or another."""
    s = ctx.settings
    proc = _context().Process(target=_main, args=(s, job_id, attempt), name=f"job-{job_id}")
    with _lock:
        proc.start()
        _live.add(proc)
    limit = s.job_timeout if s.job_timeout > 0 else math.inf
    started = time.monotonic()
    cancel_seen: float | None = None
    try:
        while True:
            proc.join(timeout=max(0.0, min(s.heartbeat_seconds, started + limit - time.monotonic())))
            if proc.exitcode is not None:
                break
            now = time.monotonic()
            if now - started >= limit:
                _end(proc)
                jobs.finish(ctx.db, job_id, attempt, "failed", TIME_LIMIT.format(limit=limit))
                log.warning("job %s killed after its %g s time limit", job_id, limit)
                return
            owned, cancel = _beat(ctx, job_id, attempt)
            if not owned:
                _end(proc)
                log.warning("job %s: this run lost its lease; its process was stopped", job_id)
                return
            if cancel and cancel_seen is None:
                cancel_seen = now   # the job's own progress callback normally stops it well before the next beat
            elif cancel and cancel_seen is not None and now - cancel_seen >= s.heartbeat_seconds:
                _end(proc)
                jobs.finish(ctx.db, job_id, attempt, "cancelled")
                log.info("job %s did not stop on cancel by itself: killed", job_id)
                return
        if proc.exitcode != 0 and not _stopping.is_set():  # it ended without recording an end (or finish() no-ops)
            how = f"killed by signal {-proc.exitcode}" if proc.exitcode < 0 else f"exit code {proc.exitcode}"
            jobs.finish(ctx.db, job_id, attempt, "failed",
                        f"the job's process ended unexpectedly ({how}; out of memory?): see the worker log, "
                        "and retry with fewer or smaller images")
            log.error("job %s: its process ended unexpectedly (%s)", job_id, how)
    finally:
        if proc.exitcode is None:  # interrupted (worker stopping): never leave it running unsupervised
            _end(proc)
        with _lock:
            _live.discard(proc)


def _end(proc: mp.process.BaseProcess) -> None:
    """Kill the job process (and what it started) and reap it: after this it can write nothing more."""
    if proc.pid is not None:   # None: never started
        kill_tree(proc.pid)
    proc.join()


def prepare() -> None:
    """Start the fork server now and wait until it has imported the job code (a second, more on a busy
    machine), rather than in the first job's time: a job's process start waits for it, and no heartbeat
    is written meanwhile, so a slow first start could cost the job its lease."""
    ctx = _context()
    if ctx.get_start_method() == "forkserver":
        ready = ctx.Process(target=_ready, name="fork-server-ready")
        ready.start()  # returns once the fork server serves processes
        ready.join()


def _ready() -> None:
    """A process that does nothing: starting one proves the fork server is serving."""


def stop_all() -> None:
    """Kill every running job process of this worker (it is stopping now; recovery retries the jobs)."""
    _stopping.set()
    with _lock:
        for proc in list(_live):
            if proc.exitcode is None and proc.pid is not None:
                kill_tree(proc.pid)


def _beat(ctx: Context, job_id: str, attempt: int) -> tuple[bool, bool]:
    """(still owned, cancel requested); a busy database now and then counts as both fine."""
    try:
        if not jobs.heartbeat(ctx.db, job_id, attempt):
            return False, False
        job = jobs.get(ctx.db, job_id)
        return True, bool(job and job["cancel_requested"])
    except Exception:
        return True, False


def kill_tree(pid: int) -> None:
    """SIGKILL a process and everything it started. Each is stopped (SIGSTOP) before its children are
    listed, so none can start another meanwhile; a child killed first would hide its own children."""
    seen, todo = set(), [pid]
    while todo:
        p = todo.pop()
        if p in seen:
            continue
        seen.add(p)
        _signal(p, signal.SIGSTOP)
        todo += _children(p)
    for p in seen:
        _signal(p, signal.SIGKILL)


def _children(pid: int) -> list[int]:
    """Child pids from /proc (Linux); elsewhere none: only the job process itself is killed."""
    kids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            ppid = int(stat.read_text().rsplit(")", 1)[1].split()[1])  # "pid (name) state ppid ..."
        except (OSError, IndexError, ValueError):
            continue
        if ppid == pid:
            kids.append(int(stat.parent.name))
    return kids


def _signal(pid: int, sig: int) -> None:
    try:
        os.kill(pid, sig)
    except (ProcessLookupError, PermissionError):
        pass


def _context():
    """The fork server (preloaded with the job code) where there is one, else spawn; never plain fork:
    the worker has threads (huey's, the maintenance ticker) whose locks a forked child would inherit held."""
    if "forkserver" in mp.get_all_start_methods():
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(["backend.queue.execute"])
        return ctx
    return mp.get_context("spawn")


def _main(settings: Settings, job_id: str, attempt: int) -> None:
    """The job process: die with the fork server, the worker's logging and thread limits, then the job."""
    from calib_core.lifetime import die_with_parent

    die_with_parent()
    _yield_to_the_api(settings.worker_nice)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    if settings.blas_threads > 0:
        from threadpoolctl import threadpool_limits

        threadpool_limits(limits=settings.blas_threads)
    from .execute import run_claimed

    run_claimed(Context.open(settings), job_id, attempt)


def _yield_to_the_api(niceness: int) -> None:
    """Linux: the job takes the CPU only when the API (and other work) does not want it.

    - a session of its own, its group niced: with autogroup scheduling (the default on desktops and many
      servers) CPU is shared fairly between sessions first and by niceness only inside one. In the API's
      session a job spent the session's share, and the API then waited behind other sessions at every
      request (status reads p99 1.2-2.4 s with a job running, 20-110 ms without); in its own session
      at nice 0 it still took a session's full share (p99 1.5 s). Its own group at FREECAL_WORKER_NICE
      gives the niceness its classic meaning: jobs yield to everything else on the machine;
    - SCHED_BATCH: the scheduler never lets the job preempt a thread that wakes for a request.
    A detection's pool inherits all of it. The job still ends with its worker (die_with_parent)."""
    try:
        os.setsid()
    except OSError:
        pass
    try:
        Path("/proc/self/autogroup").write_text(str(niceness))
    except OSError:
        pass  # no autogroups here: the process's own niceness (from its worker) orders it
    try:
        os.sched_setscheduler(0, os.SCHED_BATCH, os.sched_param(0))
    except (AttributeError, OSError):
        pass

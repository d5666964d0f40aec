"""What /api/health reports: whether every part that runs jobs and keeps data works, and if not,
what is wrong and what to do ("degraded": the service answers, but jobs or writes do not work)."""
from __future__ import annotations

import os
import time

from ...base.context import Context
from ...base.repository import jobs, workers
from ...base.storage import storage_failure
from ...queue.recovery import stuck_ids
from ...queue.tasks import Queue
from ..schemas import Health

VERSION = "0.1.0"
PROBE_SECONDS = 2.0   # health may be polled many times a second: the data directory is tried at most this often
_probes: dict[str, tuple[float, str | None]] = {}


def assess(ctx: Context, queue: Queue) -> Health:
    s = ctx.settings
    live = workers.live(ctx.db, s.lease_seconds)
    counts = jobs.count_by_state(ctx.db)
    queue_problem = queue.problem()
    storage_problem = storage_condition(ctx)
    problems = [storage_problem] if storage_problem else []
    if len(live) < s.workers:
        problems.append(f"{len(live)} of the {s.workers} worker(s) the service should have (FREECAL_WORKERS) "
                        "are alive: queued jobs wait; " + (
                            "workers cannot record that they are alive while the data directory takes no writes"
                            if storage_problem else "`freecal serve` starts dead workers again within seconds, "
                            "otherwise start one with `freecal worker`"))
    stuck = stuck_jobs(ctx)
    if stuck:
        problems.append(stuck)
    if queue_problem is not None:
        problems.append(queue_error(ctx, queue_problem))
    return Health(status="degraded" if problems else "ok", problems=problems, version=VERSION, queue=s.queue,
                  workers=len(live), workers_expected=s.workers, jobs=counts, storage_writable=storage_problem is None,
                  queue_available=queue_problem is None,
                  queue_error=None if queue_problem is None else queue_error(ctx, queue_problem),
                  max_files=s.max_files, max_upload_bytes=s.max_upload_bytes)


def queue_error(ctx: Context, problem: str) -> str:
    return (f"the job queue ({ctx.settings.redis_url}) is unreachable ({problem}): new jobs answer 503 until it is "
            "back; reads work")


def stuck_jobs(ctx: Context) -> str | None:
    """Jobs queued longer than a lease while a worker could take them (or no worker is alive)."""
    waiting, live = stuck_ids(ctx)
    lease = ctx.settings.lease_seconds
    if not waiting:
        return None
    if not live:
        return (f"{len(waiting)} job(s) have waited more than {lease:g} s and no worker is running: "
                "start one (`freecal serve` does, or `freecal worker`)")
    return (f"{len(waiting)} job(s) have waited more than {lease:g} s while a worker is idle: the queue did not "
            "deliver them; they are being sent again. If they stay queued, restart the service")


def storage_condition(ctx: Context) -> str | None:
    """Why the data directory takes no writes now (full, read-only), tried at most every PROBE_SECONDS."""
    key = str(ctx.settings.data_dir)
    at, problem = _probes.get(key, (-PROBE_SECONDS, None))
    now = time.monotonic()
    if now - at >= PROBE_SECONDS:
        problem = _probe(ctx.settings.data_dir)
        _probes[key] = (now, problem)
    return problem


def _probe(data_dir) -> str | None:
    path = data_dir / f".health-probe-{os.getpid()}"
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        try:
            os.write(fd, b"\0" * 4096)  # a whole block: a full disk refuses it even where an empty file fits
            os.fsync(fd)
        finally:
            os.close(fd)
            os.unlink(path)
    except OSError as exc:
        answer = storage_failure(exc)
        if answer is not None and answer[0] == 507:
            return (f"the data directory {data_dir} is full: uploads and new jobs answer 507 and running jobs "
                    "cannot store their results; free space there. Reads and downloads work")
        return (f"the data directory {data_dir} cannot be written ({exc.strerror or exc}): uploads and new jobs "
                "answer 503; make FREECAL_DATA_DIR writable. Reads and downloads work")
    return None

"""Run one job by id: claim it, run it in a job process, record how it ended.

``execute`` runs in a worker thread: it claims the job and hands it to
``job_process.supervise`` (heartbeat, time limit, kill). ``run_claimed`` runs
in the job process: it dispatches on the job's kind. Errors a user can cause
(``CalibError``) fail the job with their message; anything else fails it with
a plain sentence (the traceback goes to the worker's log, never to the client).
"""
from __future__ import annotations

import logging

from calib_core.errors import CalibError
from calib_core.fitting.solve import Cancelled

from ..base.context import Context
from ..base.repository import jobs
from . import calibrate_job, detect_job, job_process, rig_job
from .lease import WORKER_ID, JobRun

log = logging.getLogger("freecal.worker")
RUNNERS = {"detect": detect_job.run, "calibrate": calibrate_job.run, "rig": rig_job.run}


def execute(ctx: Context, job_id: str) -> list[str]:
    """Run the job; returns the ids of jobs to send to the queue now (the calibrations a
    finished detection released)."""
    job = jobs.get(ctx.db, job_id)
    if job is None or _waits_for_detection(ctx, job):
        return []
    attempt = jobs.claim(ctx.db, job_id, WORKER_ID)
    if attempt is None:
        return []  # cancelled, deleted, or already taken by another worker
    log.info("job %s (%s) attempt %d started", job_id, job["kind"], attempt)
    try:
        job_process.supervise(ctx, job_id, attempt)
    finally:
        released = jobs.queued_on_set(ctx.db, job["set_id"]) if job["kind"] == "detect" and job["set_id"] else []
    return released


def _waits_for_detection(ctx: Context, job: dict) -> bool:
    """A calibration of a set whose detection has not ended stays queued (the detection's end sends it
    again); one whose detection failed or was cancelled fails, saying why."""
    if job["kind"] != "calibrate" or not job["set_id"] or job["state"] != "queued":
        return False
    detection = jobs.latest_detection(ctx.db, job["set_id"])
    if detection is None or detection["state"] == "done":
        return False
    if detection["state"] in jobs.ACTIVE:
        return True
    why = f" ({detection['error']})" if detection["error"] else ""
    jobs.fail_queued(ctx.db, job["id"], f"the set's corner detection {detection['state']}{why}, so there was "
                                        "nothing to calibrate: see why, fix it (the board's spec, the photos), and "
                                        "run again")
    return True


def run_claimed(ctx: Context, job_id: str, attempt: int) -> None:
    """The job itself (in its job process): its runner, and the end it reached."""
    job = jobs.get(ctx.db, job_id)
    if job is None:
        return
    run = JobRun(ctx, job_id, attempt)
    try:
        fields = RUNNERS[job["kind"]](ctx, job, run)
    except Cancelled as exc:
        if not run.lost:
            run.finish("cancelled", None)
        log.info("job %s stopped: %s", job_id, exc)
        return
    except CalibError as exc:
        run.finish("failed", str(exc))
        log.info("job %s failed: %s", job_id, exc)
        return
    except Exception as exc:
        from ..base.storage import storage_failure

        full = storage_failure(exc)
        if full is not None:  # disk full / read-only data dir: say so, not "internal error"
            log.error("job %s: %s", job_id, exc)
            run.finish("failed", full[1].replace("nothing was stored", "its results could not be written"))
            return
        log.exception("job %s crashed", job_id)
        run.finish("failed", "internal error while running the job (see the worker log); "
                             "retry, and report it if it persists")
        return
    if not run.finish("done", None, **fields):
        log.warning("job %s finished but no longer owned this run", job_id)
    else:
        log.info("job %s done", job_id)

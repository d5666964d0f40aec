"""Run one job by id: claim it, dispatch on its kind, record how it ended.

Errors a user can cause (``CalibError``) fail the job with their message;
anything else fails it with a plain sentence (the traceback goes to the
worker's log, never to the client).
"""
from __future__ import annotations

import logging

from calib_core.errors import CalibError
from calib_core.solve import Cancelled

from ..app.context import Context
from ..app.repository import jobs
from . import calibrate_job, detect_job
from .lease import WORKER_ID, JobRun

log = logging.getLogger("freecal.worker")
RUNNERS = {"detect": detect_job.run, "calibrate": calibrate_job.run}


def execute(ctx: Context, job_id: str) -> None:
    attempt = jobs.claim(ctx.db, job_id, WORKER_ID)
    if attempt is None:
        return  # cancelled, deleted, or already taken by another worker
    job = jobs.get(ctx.db, job_id)
    if job is None:
        return
    log.info("job %s (%s) attempt %d started", job_id, job["kind"], attempt)
    with JobRun(ctx, job_id, attempt) as run:
        try:
            fields = RUNNERS[job["kind"]](ctx, job, run)
        except Cancelled as exc:
            if not run.lost.is_set():
                run.finish("cancelled", None)
            log.info("job %s stopped: %s", job_id, exc)
            return
        except CalibError as exc:
            run.finish("failed", str(exc))
            log.info("job %s failed: %s", job_id, exc)
            return
        except Exception as exc:
            from ..app.errors import storage_failure

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

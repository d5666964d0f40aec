"""Hand a created job to the queue, or undo what was created for it: a client
never sees a set or job that no worker will ever take."""
from __future__ import annotations

from collections.abc import Callable

from ...base.context import Context
from ...base.repository import jobs
from ...queue.tasks import Queue, QueueUnavailable
from ..errors import ApiError


def enqueue_or_undo(ctx: Context, queue: Queue, job_id: str, undo: Callable[[], None]) -> None:
    """Enqueue ``job_id``; if the queue cannot take it, run ``undo`` and answer 503."""
    try:
        queue.enqueue(job_id)
    except QueueUnavailable as exc:
        undo()
        raise unavailable(ctx, exc) from None


def enqueue_job(ctx: Context, queue: Queue, job_id: str) -> None:
    """Enqueue a job just created; if the queue cannot take it, the job and its folder go again (503)."""
    def undo() -> None:
        jobs.delete(ctx.db, job_id)
        ctx.storage.remove_job(job_id)

    enqueue_or_undo(ctx, queue, job_id, undo)


def unavailable(ctx: Context, exc: Exception) -> ApiError:
    where = f"Redis at {ctx.settings.redis_url}" if ctx.settings.queue == "redis" else "the SQLite queue"
    return ApiError(503, f"the job queue ({where}) cannot take jobs right now ({exc}); "
                         "check that it is running and retry")

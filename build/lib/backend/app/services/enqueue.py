"""Hand a created job to the queue, or undo what was created for it: a client
never sees a set or job that no worker will ever take."""
from __future__ import annotations

from collections.abc import Callable

from ...base.context import Context
from ...queue.tasks import Queue, QueueUnavailable
from ..errors import ApiError


def enqueue_or_undo(ctx: Context, queue: Queue, job_id: str, undo: Callable[[], None]) -> None:
    """Enqueue ``job_id``; if the queue cannot take it, run ``undo`` and answer 503."""
    try:
        queue.enqueue(job_id)
    except QueueUnavailable as exc:
        undo()
        raise unavailable(ctx, exc) from None


def unavailable(ctx: Context, exc: Exception) -> ApiError:
    where = f"Redis at {ctx.settings.redis_url}" if ctx.settings.queue == "redis" else "the SQLite queue"
    return ApiError(503, f"the job queue ({where}) cannot take jobs right now ({exc}); "
                         "check that it is running and retry")

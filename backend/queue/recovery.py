"""Jobs whose worker died: retried or failed with the reason, never 'running' forever.

``recover_stale`` runs periodically in the API process and in every worker
(any of them may do it: each state change is one conditional UPDATE, so two
recoverers cannot both re-queue the same run). ``requeue_pending`` runs once
at API start-up: the database, not the queue, is the record of what is
queued, so a message lost with a crash is sent again (a duplicate is harmless:
only one claim of a queued job succeeds).
"""
from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from ..app.context import Context
from ..app.repository import jobs
from .tasks import Queue

log = logging.getLogger("freecal.recovery")


def recover_stale(ctx: Context, queue: Queue) -> int:
    lease = ctx.settings.lease_seconds
    n = 0
    for job in jobs.stale(ctx.db, lease):
        reason = (f"the worker running it ({job['worker']}) stopped sending heartbeats for more than "
                  f"{lease:g} s (it was stopped or crashed)")
        new = jobs.requeue_or_fail(ctx.db, job["id"], job["attempts"], ctx.settings.max_attempts, reason)
        if new is None:
            continue
        n += 1
        log.warning("job %s: worker %s silent, now %s", job["id"], job["worker"], new)
        if new == "queued":
            queue.enqueue(job["id"])
    return n


def requeue_pending(ctx: Context, queue: Queue) -> int:
    ids = jobs.queued_ids(ctx.db)
    for job_id, _ in ids:
        queue.enqueue(job_id)
    return len(ids)


class Periodic(threading.Thread):
    """Calls ``fn`` every ``seconds`` until stopped; errors are logged, not fatal."""

    def __init__(self, seconds: float, fn: Callable[[], object], name: str):
        super().__init__(name=name, daemon=True)
        self.seconds, self.fn = seconds, fn
        self.stopped = threading.Event()

    def run(self) -> None:
        while not self.stopped.wait(self.seconds):
            try:
                self.fn()
            except Exception:
                log.exception("%s failed", self.name)

    def stop(self) -> None:
        self.stopped.set()

"""Jobs whose worker died: retried or failed with the reason, never 'running' forever.

``recover_stale`` runs periodically in the API process and in every worker
(any of them may do it: each state change is one conditional UPDATE, so two
recoverers cannot both re-queue the same run). ``requeue_pending`` runs once
at API start-up: the database, not the queue, is the record of what is
queued, so a message lost with a crash is sent again (a duplicate is harmless:
only one claim of a queued job succeeds). ``resend_stuck`` runs periodically in
the API: a job that waits longer than a lease while a worker idles lost its
message (a Redis restarted without its data): it is sent again.
"""
from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable

from ..base.context import Context
from ..base.repository import jobs, workers
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


def stuck_ids(ctx: Context) -> tuple[list[str], int]:
    """(queued jobs that waited longer than a lease while a worker could take them, live workers)."""
    s = ctx.settings
    live = len(workers.live(ctx.db, s.lease_seconds))
    if live and jobs.count_by_state(ctx.db).get("running", 0) >= live * s.worker_threads:
        return [], live  # every worker is busy: waiting is normal
    return jobs.waiting(ctx.db, s.lease_seconds, s.lease_seconds), live


def resend_stuck(ctx: Context, queue: Queue, sent: dict[str, float]) -> int:
    """Send stuck jobs again, each at most once per lease (``sent``: job id → when, kept by the caller)."""
    ids, live = stuck_ids(ctx)
    if not live:
        return 0  # nobody to deliver to: health says so
    now = time.monotonic()
    for job_id in list(sent):
        if job_id not in ids:
            del sent[job_id]
    n = 0
    for job_id in ids:
        if now - sent.get(job_id, -math.inf) >= ctx.settings.lease_seconds:
            queue.enqueue(job_id)
            sent[job_id] = now
            n += 1
            log.warning("job %s waited more than %g s with a worker idle: sent again", job_id,
                        ctx.settings.lease_seconds)
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

"""The one huey task: run job ``job_id`` (its kind, inputs and settings are in the database)."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from huey import Huey

from ..base.context import Context
from .instance import build_huey


class QueueUnavailable(Exception):
    """The queue's backend (Redis, or the SQLite queue file) cannot take the job now."""


@dataclass
class Queue:
    huey: Huey
    _run: Callable[[str], object]  # huey's TaskWrapper: calling it enqueues

    def enqueue(self, job_id: str) -> None:
        try:
            self._run(job_id)
        except Exception as exc:  # redis ConnectionError, sqlite OperationalError, ...
            raise QueueUnavailable(f"{type(exc).__name__}: {exc}") from exc

    def problem(self) -> str | None:
        """Why the queue cannot take jobs now (Redis down), or None when it can."""
        conn = getattr(self.huey.storage, "conn", None)
        if conn is None or not hasattr(conn, "ping"):
            return None  # SQLite: a file beside the database
        try:
            conn.ping()
        except Exception as exc:
            return f"{type(exc).__name__}: {exc}"
        return None


def build_queue(ctx: Context) -> Queue:
    huey = build_huey(ctx.settings)

    @huey.task(name="freecal.run")
    def run(job_id: str) -> None:
        from .execute import execute  # calib_core loads only where jobs run

        for released in execute(ctx, job_id):  # calibrations that waited for this detection
            queue.enqueue(released)

    queue = Queue(huey, run)
    return queue

"""One run of a job: its lease (a heartbeat thread), its progress, its end.

The heartbeat runs in its own thread so a long solver step cannot make a live
job look dead; the progress callback given to calib_core stores the stage and
percentage (throttled) and raises ``Cancelled`` when the job's row asks for
cancellation or this run no longer owns the job.
"""
from __future__ import annotations

import os
import socket
import threading
import time
from typing import Any

from calib_core.solve import Cancelled

from ..app.context import Context
from ..app.repository import jobs

WORKER_ID = f"{socket.gethostname()}:{os.getpid()}"
MIN_REPORT_SECONDS = 0.25


class JobRun:
    def __init__(self, ctx: Context, job_id: str, attempt: int):
        self.ctx, self.job_id, self.attempt = ctx, job_id, attempt
        self.lost = threading.Event()
        self._stop = threading.Event()
        self._stage: str | None = None
        self._stage_t0 = time.perf_counter()
        self.stages: dict[str, float] = {}
        self._last_report = 0.0
        self._started = time.monotonic()
        self.timed_out = False
        self._thread = threading.Thread(target=self._beat, name=f"lease-{job_id}", daemon=True)

    def __enter__(self) -> "JobRun":
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join(timeout=5)

    def _beat(self) -> None:
        limit = self.ctx.settings.job_timeout
        every = self.ctx.settings.heartbeat_seconds if limit <= 0 else min(self.ctx.settings.heartbeat_seconds, limit)
        while not self._stop.wait(every):
            if limit > 0 and time.monotonic() - self._started > limit:
                # FREECAL_JOB_TIMEOUT: fail it now (the API shows why at once); the solver stops at its
                # next progress step, since this run no longer owns the job
                self.timed_out = True
                self.finish("failed", f"the job ran longer than the time limit of {limit:g} s "
                                      "(FREECAL_JOB_TIMEOUT) and was stopped: use fewer views or knot intervals, "
                                      "fewer iterations, or ask the administrator for a longer limit")
                self.lost.set()
                return
            try:
                if not jobs.heartbeat(self.ctx.db, self.job_id, self.attempt):
                    self.lost.set()
                    return
            except Exception:  # a busy database now and then must not kill the lease
                pass

    def progress(self, stage: str, fraction: float, lo: float = 0.0, hi: float = 1.0) -> None:
        """calib_core's ``progress(stage, fraction)``, mapped into [lo, hi] of the job."""
        if stage == "done":
            return
        now = time.perf_counter()
        changed = stage != self._stage
        if changed:
            if self._stage is not None:
                self.stages[self._stage] = self.stages.get(self._stage, 0.0) + now - self._stage_t0
            self._stage, self._stage_t0 = stage, now
        if self.lost.is_set():
            raise Cancelled("this run lost its lease")
        if not changed and now - self._last_report < MIN_REPORT_SECONDS:
            return
        self._last_report = now
        pct = 100.0 * (lo + (hi - lo) * min(max(float(fraction), 0.0), 1.0))
        owned, cancel = jobs.report(self.ctx.db, self.job_id, self.attempt, stage, round(pct, 1), self.stage_times())
        if not owned:
            self.lost.set()
            raise Cancelled("this run lost its lease")
        if cancel:
            raise Cancelled("cancelled on request")

    def stage_times(self) -> dict[str, float]:
        out = dict(self.stages)
        if self._stage is not None:
            out[self._stage] = out.get(self._stage, 0.0) + time.perf_counter() - self._stage_t0
        return {k: round(v, 3) for k, v in out.items()}

    def finish(self, state: str, error: str | None = None, **fields: Any) -> bool:
        return jobs.finish(self.ctx.db, self.job_id, self.attempt, state, error,
                           stages=self.stage_times(), **fields)

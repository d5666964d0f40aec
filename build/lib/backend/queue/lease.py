"""One run of a job, inside its job process: its progress and its end.

The progress callback given to calib_core stores the stage and percentage
(throttled) and raises ``Cancelled`` when the job's row asks for cancellation
or this run no longer owns the job. The lease itself (heartbeat, time limit,
killing a run that will not stop) is kept by the worker that started the job
process (``job_process.supervise``): a solver stuck in C cannot stall it.
"""
from __future__ import annotations

import os
import socket
import time
from typing import Any

from calib_core.fitting.solve import Cancelled

from ..base.context import Context
from ..base.repository import jobs

WORKER_ID = f"{socket.gethostname()}:{os.getpid()}"  # read in the worker process (the claim), not in job processes
MIN_REPORT_SECONDS = 0.25


class JobRun:
    def __init__(self, ctx: Context, job_id: str, attempt: int):
        self.ctx, self.job_id, self.attempt = ctx, job_id, attempt
        self.lost = False   # another run owns the job now (or it ended): write nothing more
        self._stage: str | None = None
        self._stage_t0 = time.perf_counter()
        self.stages: dict[str, float] = {}
        self._last_report = 0.0

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
        if self.lost:
            raise Cancelled("this run lost its lease")
        if not changed and now - self._last_report < MIN_REPORT_SECONDS:
            return
        self._last_report = now
        pct = 100.0 * (lo + (hi - lo) * min(max(float(fraction), 0.0), 1.0))
        owned, cancel = jobs.report(self.ctx.db, self.job_id, self.attempt, stage, round(pct, 1), self.stage_times())
        if not owned:
            self.lost = True
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

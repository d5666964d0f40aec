"""Progress on standard error, drawn from calib_core's callbacks: on a terminal a
bar with the time elapsed and an estimate of the time left (rich), elsewhere (a
log file, a pipe, CI) plain lines, one per stage.

calib_core only calls ``progress(stage, fraction)`` (``methods.common.Progress``)
or ``progress(done, total)`` (detection); the drawing lives here. Each class is a
context manager: the bar is closed when the work ends, or fails.
"""
from __future__ import annotations

import sys
import time
from typing import Any

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskProgressColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

PLAIN_EVERY_SECONDS = 5.0  # plain count lines: at most one per this many seconds (and at 25, 50, 75 %)


def _console() -> Console:
    return Console(stderr=True)


class _Bar:
    """A rich bar on a terminal, or None elsewhere and when quiet."""

    def __init__(self, quiet: bool, *columns: Any):
        console = _console()
        self.bar: Progress | None = None
        if not quiet and console.is_terminal:
            self.bar = Progress(*columns, console=console, transient=False)
        self.t0 = time.perf_counter()

    def __enter__(self):
        if self.bar is not None:
            self.bar.start()
        return self

    def __exit__(self, *exc) -> None:
        if self.bar is not None:
            self.bar.stop()

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0


class StageProgress(_Bar):
    """``progress(stage, fraction)`` of a calibration or a comparison: the stage's
    name (with the candidate model it belongs to) beside the bar, or a plain line
    each time the stage changes."""

    def __init__(self, quiet: bool = False, what: str = "calibrating"):
        super().__init__(quiet, TextColumn("{task.description}"), BarColumn(), TaskProgressColumn(),
                         TimeElapsedColumn(), TextColumn("left"), TimeRemainingColumn())
        self.quiet, self.what = quiet, what
        self.stage: str | None = None
        self.task = self.bar.add_task(what, total=1.0) if self.bar is not None else None

    def __call__(self, stage: str, fraction: float) -> None:
        fraction = min(max(float(fraction), 0.0), 1.0)
        if self.bar is not None and self.task is not None:
            self.bar.update(self.task, completed=fraction, description=stage)
            return
        if self.quiet or stage == self.stage:
            return
        self.stage = stage
        print(f"[{self.elapsed():7.2f} s] {100 * fraction:3.0f} %  {stage}", file=sys.stderr, flush=True)


class CountProgress(_Bar):
    """``progress(done, total)`` (images detected): a bar with the count, the
    rate and the time left, or a plain line now and then with the same."""

    def __init__(self, quiet: bool = False, what: str = "detecting", unit: str = "images"):
        super().__init__(quiet, TextColumn(what), BarColumn(), MofNCompleteColumn(), TextColumn(unit),
                         TimeElapsedColumn(), TextColumn("left"), TimeRemainingColumn())
        self.quiet, self.what, self.unit = quiet, what, unit
        self.task: Any = None
        self.last_line = -1.0
        self.last_quarter = 0

    def __call__(self, done: int, total: int) -> None:
        if self.bar is not None:
            if self.task is None:
                self.task = self.bar.add_task(self.what, total=total)
            self.bar.update(self.task, completed=done, total=total)
            return
        if self.quiet:
            return
        now, quarter = self.elapsed(), (4 * done) // max(total, 1)
        if done < total and quarter == self.last_quarter and now - self.last_line < PLAIN_EVERY_SECONDS:
            return
        self.last_line, self.last_quarter = now, quarter
        rate = done / max(now, 1e-9)
        left = f", about {(total - done) / rate:.0f} s left" if 0 < done < total else ""
        print(f"[{now:7.2f} s] {self.what}: {done}/{total} {self.unit} ({rate:.1f}/s{left})", file=sys.stderr, flush=True)

"""`freecal serve` keeps its workers running: a worker that dies is started again.

A worker can die without a word (kill -9, out of memory, a crash in C); its
running job is then the lease's to recover (retried, or failed with the reason),
but the queue needs a worker to run anything at all. So the supervisor checks
its worker processes every ``CHECK_SECONDS`` and starts a new one in place of
each that exited. A worker that keeps dying soon after it starts (a broken
install, a data directory gone) is started again after a pause that doubles each
time, up to ``MAX_PAUSE_SECONDS``, so it never spins a core; /api/health says
"degraded" meanwhile (fewer live workers than ``FREECAL_WORKERS``).

Workers are started by the supervisor's own thread and ended by it: on Linux a
worker dies with the thread that started it (``PR_SET_PDEATHSIG``), so the
thread must outlive its workers until it has stopped them itself.
"""
from __future__ import annotations

import logging
import subprocess
import threading
import time
from dataclasses import dataclass

log = logging.getLogger("freecal.serve")
CHECK_SECONDS = 0.5
HEALTHY_SECONDS = 30.0    # a worker that ran this long died of something else than its start: restart at once
FIRST_PAUSE_SECONDS = 1.0
MAX_PAUSE_SECONDS = 30.0
STOP_SECONDS = 10.0       # SIGTERM, then this long before SIGKILL


@dataclass
class Slot:
    proc: subprocess.Popen | None = None
    started: float = 0.0
    restart_at: float = 0.0
    pause: float = 0.0
    restarts: int = 0


class Supervisor(threading.Thread):
    def __init__(self, argv: list[str], env: dict[str, str], count: int):
        super().__init__(name="worker-supervisor", daemon=True)
        self.argv, self.env = argv, env
        self.slots = [Slot() for _ in range(max(0, count))]
        self._stopping = threading.Event()
        self._ready = threading.Event()

    def start(self) -> None:
        super().start()
        self._ready.wait()  # the first workers exist before the API answers

    def run(self) -> None:
        try:
            while True:
                self._tend(time.monotonic())
                self._ready.set()
                if self._stopping.wait(CHECK_SECONDS):
                    break
        finally:
            self._stop_workers()
            self._ready.set()

    def stop(self) -> None:
        self._stopping.set()
        if self.is_alive():
            self.join(STOP_SECONDS + 15)

    def pids(self) -> list[int]:
        return [s.proc.pid for s in self.slots if s.proc is not None and s.proc.poll() is None]

    def _tend(self, now: float) -> None:
        for k, slot in enumerate(self.slots):
            if slot.proc is not None:
                code = slot.proc.poll()
                if code is None:
                    continue
                lived = now - slot.started
                slot.pause = 0.0 if lived >= HEALTHY_SECONDS else \
                    min(MAX_PAUSE_SECONDS, max(FIRST_PAUSE_SECONDS, 2 * slot.pause))
                slot.restart_at = now + slot.pause
                how = f"killed by signal {-code}" if code < 0 else f"exit code {code}"
                log.warning("worker %d (pid %d) ended (%s) after %.0f s; starting another%s", k + 1,
                            slot.proc.pid, how, lived, f" in {slot.pause:g} s" if slot.pause else "")
                slot.proc = None
            if now >= slot.restart_at:
                slot.proc = subprocess.Popen(self.argv, env=self.env)
                slot.started = now
                if slot.restarts:
                    log.warning("worker %d started again (pid %d)", k + 1, slot.proc.pid)
                slot.restarts += 1

    def _stop_workers(self) -> None:
        live = [s.proc for s in self.slots if s.proc is not None and s.proc.poll() is None]
        for proc in live:
            proc.terminate()
        deadline = time.monotonic() + STOP_SECONDS
        for proc in live:
            try:
                proc.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()

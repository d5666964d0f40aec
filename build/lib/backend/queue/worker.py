"""The worker entry point: a huey consumer on the configured queue, plus its
heartbeat in the worker registry and the periodic recovery of stale jobs."""
from __future__ import annotations

import logging
import os
import signal
import socket
import time

from ..base.context import Context
from ..base.repository import workers
from ..base.settings import Settings
from . import job_process
from .lease import WORKER_ID
from .recovery import Periodic, recover_stale
from .tasks import build_queue

log = logging.getLogger("freecal.worker")


def run_worker(settings: Settings, threads: int | None = None, parent_pid: int | None = None) -> int:
    """Consume jobs until SIGINT (finish running jobs) or SIGTERM (stop now)."""
    if parent_pid is not None:
        from calib_core.lifetime import die_with_parent

        die_with_parent(parent_pid)  # `freecal serve` killed outright: the kernel ends us too (Linux)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    logging.getLogger("huey").setLevel(logging.WARNING)
    # OpenCV refuses to decode more pixels than the upload limit (TIFF/WebP bombs whose header
    # the API does not read); detection processes inherit it. Must precede cv2's import.
    if settings.worker_nice > 0:
        try:
            os.nice(settings.worker_nice)
        except OSError:  # not permitted here: run at the normal priority
            pass
    from threadpoolctl import threadpool_limits

    if settings.blas_threads > 0:  # 0: the libraries' default (one thread per core)
        threadpool_limits(limits=settings.blas_threads)  # process-wide, for every job this worker runs
    ctx = Context.open(settings)
    queue = build_queue(ctx)
    job_process.prepare()  # after nice and the environment above: job processes inherit both
    consumer = queue.huey.create_consumer(
        workers=threads or settings.worker_threads, worker_type="thread", periodic=False,
        initial_delay=0.05, max_delay=settings.poll_seconds, backoff=1.5)
    started = time.time()

    def maintain() -> None:
        if parent_pid is not None and os.getppid() != parent_pid:
            # the `freecal serve` that started us is gone (where the kernel did not end us): stop
            log.warning("parent process %d ended; stopping", parent_pid)
            os.kill(os.getpid(), signal.SIGTERM)
            return
        workers.beat(ctx.db, WORKER_ID, socket.gethostname(), os.getpid(), started, settings.lease_seconds)
        recover_stale(ctx, queue)

    maintain()
    ticker = Periodic(settings.heartbeat_seconds, maintain, "worker-maintenance")
    ticker.start()
    log.info("worker %s consuming the %s queue in %s", WORKER_ID, settings.queue, settings.data_dir)
    try:
        consumer.run()
    finally:
        job_process.stop_all()  # SIGTERM (stop now) leaves jobs running: end them, recovery retries them
        ticker.stop()
        workers.remove(ctx.db, WORKER_ID)
    return 0

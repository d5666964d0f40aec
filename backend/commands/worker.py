"""freecal worker [--data-dir DIR] [--queue sqlite|redis] [--redis-url URL] [--threads N]

A worker alone: consumes jobs from the configured queue and writes results to
the shared data directory. Run several (one per core) to run jobs in parallel.
"""
from __future__ import annotations

import argparse

from ..base.settings import Settings
from .output import require_service


def add_queue_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data-dir", default=None, help="database and files (FREECAL_DATA_DIR, default ./freecal-data)")
    p.add_argument("--queue", choices=("sqlite", "redis"), default=None,
                   help="the queue backend (FREECAL_QUEUE, default sqlite: a file in the data dir)")
    p.add_argument("--redis-url", default=None, help="Redis for --queue redis (FREECAL_REDIS_URL)")


def settings_of(args) -> Settings:
    return Settings.from_env(data_dir=args.data_dir, queue=args.queue, redis_url=args.redis_url)


def register(sub) -> None:
    p = sub.add_parser("worker", help="run a job worker (consumes the queue)",
                       description="Consume calibration and detection jobs from the queue.")
    add_queue_options(p)
    p.add_argument("--threads", type=int, default=None, help="jobs at once in this process (default 1)")
    p.add_argument("--parent-pid", type=int, default=None, help=argparse.SUPPRESS)  # set by `freecal serve`
    p.set_defaults(run=run)


def run(args) -> int:
    require_service("worker")
    from ..base.context import Context
    from ..queue.worker import run_worker

    settings = settings_of(args)
    Context.check_writable(settings.data_dir)
    return run_worker(settings_of(args), args.threads, args.parent_pid)

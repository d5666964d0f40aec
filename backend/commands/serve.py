"""freecal serve [--host 127.0.0.1] [--port 8000] [--data-dir DIR] [--workers 1]

The API and its workers on one machine, nothing else to install: the workers
are child processes (``freecal worker``) on the embedded SQLite queue, so a
long calibration never slows the API (no shared GIL) and a crashed job never
takes the API down. A worker that dies is started again (``queue.supervisor``);
the workers stop with the server, and on their own if it dies.
"""
from __future__ import annotations

import os
import sys
from dataclasses import replace

from .output import require_service
from .worker import add_queue_options, settings_of


def register(sub) -> None:
    p = sub.add_parser("serve", help="start the API (and workers) on this machine",
                       description="Start the HTTP API (OpenAPI docs at /docs) and embedded workers.")
    p.add_argument("--host", default="127.0.0.1", help="interface to bind (default loopback only)")
    p.add_argument("--port", type=int, default=8000)
    add_queue_options(p)
    p.add_argument("--workers", type=int, default=None,
                   help="worker processes to keep running beside the API (FREECAL_WORKERS, default 1; "
                        "0: run them elsewhere with `freecal worker`)")
    p.set_defaults(run=run)


def run(args) -> int:
    require_service("serve")
    import uvicorn

    from ..app.header_limit import uvicorn_options
    from ..app.main import create_app

    settings = replace(settings_of(args), host=args.host)  # a name the API answers to (Host header)
    if args.workers is not None:
        settings = replace(settings, workers=max(0, args.workers))  # health expects this many
    from ..base.context import Context

    Context.check_writable(settings.data_dir)  # a clear line now, not a traceback from every process
    from ..app.security import check_viewer_exposure

    check_viewer_exposure(settings)  # before any worker starts (create_app checks it again)
    from ..queue.supervisor import Supervisor

    env = {**os.environ, **settings.to_env()}
    argv = [sys.executable, "-m", "backend.cli", "worker", "--parent-pid", str(os.getpid())]
    supervisor = Supervisor(argv, env, settings.workers)
    supervisor.start()
    print(f"freecal: API on http://{args.host}:{args.port} (docs at /docs), {settings.workers} worker(s), "
          f"data in {settings.data_dir}", file=sys.stderr, flush=True)
    try:
        uvicorn.run(create_app(settings), host=args.host, port=args.port, **uvicorn_options())
    finally:
        supervisor.stop()
    return 0

"""The huey instance: SqliteHuey in the data directory by default, RedisHuey when configured.

``results=False``: tasks return nothing through huey (results and progress go
to the database and files), which sidesteps huey's read-deletes-result and
intermediate-error gotchas altogether. Retries are ours too (the lease), since
huey cannot retry a task whose process died.
"""
from __future__ import annotations

from huey import Huey, RedisHuey, SqliteHuey

from ..base.settings import Settings

NAME = "freecal"


def build_huey(settings: Settings) -> Huey:
    if settings.queue == "redis":
        # blocking reads: a worker wakes as soon as a job is pushed
        # a bounded connect: an unreachable Redis answers 503 in seconds, never hangs a request
        from redis import ConnectionPool

        pool = ConnectionPool.from_url(settings.redis_url, socket_connect_timeout=3)
        return RedisHuey(NAME, connection_pool=pool, results=False, blocking=True, read_timeout=1)
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    return SqliteHuey(NAME, filename=str(settings.queue_path), results=False)

"""Service settings from ``FREECAL_*`` environment variables, with safe defaults.

A plain dataclass (no pydantic-settings dependency): the API process, the
worker processes and the test fixtures all build it the same way, from the
environment, so one exported variable configures every part.
"""
from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any, Literal

MB = 1024 * 1024


@dataclass(frozen=True)
class Settings:
    data_dir: Path = Path("freecal-data")
    # "sqlite" (embedded, a file in data_dir) or "redis" (several machines/containers)
    queue: Literal["sqlite", "redis"] = "sqlite"
    redis_url: str = "redis://127.0.0.1:6379/0"
    # Upload limits: a client can cause these, so they answer 413/422, never 500.
    max_upload_bytes: int = 1024 * MB
    max_files: int = 500
    max_image_pixels: int = 50_000_000
    max_observations_bytes: int = 64 * MB
    # Leases: a running job's worker writes a heartbeat every heartbeat_seconds;
    # one silent for lease_seconds is taken to be dead and is retried (up to
    # max_attempts runs in all) or failed with the reason.
    heartbeat_seconds: float = 5.0
    lease_seconds: float = 60.0
    max_attempts: int = 2
    # SqliteHuey polls; this caps the wait between polls of an idle queue.
    poll_seconds: float = 1.0
    # Worker processes the service should have: `freecal serve` starts this many and starts a
    # new one in place of any that dies; /api/health is "degraded" while fewer are alive.
    # With workers run elsewhere (`serve --workers 0`, docker compose), set it to their number.
    workers: int = 1
    # Worker threads per worker process (CPU-bound jobs scale better by processes).
    worker_threads: int = 1
    # BLAS/OpenMP threads per worker: the solver gains nothing from more, and
    # several workers (or a busy machine) lose up to 4x to oversubscription.
    # 0 leaves the libraries' default.
    blas_threads: int = 1
    # The 3D view (viser) runs inside the API process on its own port; viser takes the
    # next free port if this one is taken (0: any free port). Browsers reach it through
    # the API's /viewer proxy (which checks the token), so it needs no other interface;
    # with a token set, a non-loopback viewer_host is refused (viser cannot check tokens).
    viewer: bool = True
    viewer_port: int = 8080
    viewer_host: str = "127.0.0.1"
    # Hardening (docs/service.md, "Security" and "Limits"):
    # token: when set, every /api request needs "Authorization: Bearer <token>" or ?token=<token>.
    token: str = ""
    # cors_origins: comma-separated origins allowed to call the API from another site ("" = none, closed);
    # they may also send POST/PUT/PATCH/DELETE, which other sites' pages may not (403).
    cors_origins: str = ""
    # The API's own address (`freecal serve --host`): a name it answers to, beside the loopback names.
    host: str = "127.0.0.1"
    # allowed_hosts: comma-separated more names the Host header may carry (DNS-rebinding defence;
    # 400 for any other name; "*" = any, e.g. behind a proxy that checks the name itself).
    allowed_hosts: str = ""
    # Jobs (detections and calibrations) one client IP may have queued or running at once (429 beyond).
    max_jobs_per_client: int = 20
    # Sets the server keeps at once (507 beyond): with max_upload_bytes, a bound on its storage.
    max_sets: int = 1000
    # A request body that sends nothing for this long (seconds) is answered 408 and closed (slowloris).
    body_idle_seconds: float = 30.0
    # ... and one that arrives slower than this on average (bytes a second, after body_idle_seconds
    # of grace) too: a byte every few seconds would hold a connection for days (0 = no minimum).
    body_min_rate: float = 500.0
    # Cameras one rig job may calibrate together (POST /api/jobs with kind "rig"; 422 beyond):
    # each is a calibration of its own, then one joint fit of every camera's corners.
    max_rig_cameras: int = 8
    # A job running longer than this (seconds) is killed and failed with the reason (0 = no limit).
    # Jobs run in a child process of the worker, so the limit holds even for a solver stuck in C.
    job_timeout: float = 1800.0
    # Workers run at this niceness (0-19): a calibration yields the CPU to the API's requests,
    # so status reads stay fast while jobs run on the same cores (0: same priority).
    worker_nice: int = 10

    @property
    def db_path(self) -> Path:
        return self.data_dir / "freecal.db"

    @property
    def queue_path(self) -> Path:
        return self.data_dir / "queue.db"

    @classmethod
    def from_env(cls, env: dict[str, str] | None = None, **overrides: Any) -> Settings:
        """Read ``FREECAL_<FIELD>`` (e.g. ``FREECAL_DATA_DIR``); ``overrides`` win."""
        source: Mapping[str, str] = os.environ if env is None else env
        values: dict[str, Any] = {}
        for f in fields(cls):
            raw = source.get("FREECAL_" + f.name.upper())
            if raw is None or raw == "":
                continue
            kind: Callable[[str], Any] = Path if f.name == "data_dir" else type(getattr(cls, f.name))
            if kind is bool:  # bool("0") is True: read the words people write
                kind = _flag
            try:
                values[f.name] = kind(raw)
            except ValueError:
                raise SystemExit(f"FREECAL_{f.name.upper()}={raw!r}: expected {kind.__name__}") from None
        settings = replace(cls(**values), **{k: v for k, v in overrides.items() if v is not None})
        if settings.workers < 0:
            raise SystemExit(f"FREECAL_WORKERS={settings.workers}: expected 0 or more")
        for name in ("max_upload_bytes", "max_files", "max_image_pixels", "max_jobs_per_client", "max_sets"):
            if getattr(settings, name) < 1:
                raise SystemExit(f"FREECAL_{name.upper()}={getattr(settings, name)}: expected a positive number")
        if not settings.body_idle_seconds > 0:
            raise SystemExit(f"FREECAL_BODY_IDLE_SECONDS={settings.body_idle_seconds}: expected a positive number")
        if not settings.body_min_rate >= 0:
            raise SystemExit(f"FREECAL_BODY_MIN_RATE={settings.body_min_rate}: expected 0 (no minimum) or more")
        if settings.max_rig_cameras < 2:
            raise SystemExit(f"FREECAL_MAX_RIG_CAMERAS={settings.max_rig_cameras}: expected 2 or more (a rig is "
                             "two or more cameras)")
        if settings.queue not in ("sqlite", "redis"):
            raise SystemExit(f"FREECAL_QUEUE={settings.queue!r}: expected 'sqlite' or 'redis'")
        return replace(settings, data_dir=Path(settings.data_dir).resolve())

    def to_env(self) -> dict[str, str]:
        """The variables that rebuild these settings in a child process."""
        return {"FREECAL_" + f.name.upper(): str(getattr(self, f.name)) for f in fields(self)}


def _flag(raw: str) -> bool:
    word = raw.strip().lower()
    if word in ("1", "true", "yes", "on"):
        return True
    if word in ("0", "false", "no", "off"):
        return False
    raise ValueError(raw)

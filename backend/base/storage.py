"""Files under the data directory: uploads and artefacts, each written atomically.

Layout::

    DATA/freecal.db                 metadata (db.py)
    DATA/queue.db                   the embedded queue (SqliteHuey)
    DATA/sets/ID/images/NAME        uploaded images
    DATA/sets/ID/observations.json  corners (detected, or uploaded)
    DATA/jobs/ID/input.json         observations given inline with the job
    DATA/jobs/ID/NAME               results (calibration.json, residuals, ...)

A file appears complete or not at all (written to a temp name in the same
directory, fsynced, then renamed), so a crash never leaves half a result.
"""
from __future__ import annotations

import errno
import json
import os
import re
import shutil
import sqlite3
import tempfile
from pathlib import Path
from typing import IO, Any, BinaryIO

CHUNK = 1024 * 1024
RIG_FILE = "rig.json"  # a done rig job's result (freecal.rig/1)
# errno values meaning "this data directory takes no writes now" (full, or read-only / not permitted)
NO_SPACE = (errno.ENOSPC, errno.EDQUOT)
READ_ONLY = (errno.EROFS, errno.EACCES, errno.EPERM)
_SAFE = re.compile(r"[^A-Za-z0-9._-]+")


class TooLarge(Exception):
    """A stream went past its byte limit."""


def safe_name(name: str) -> str:
    """A file name that cannot escape its folder (no separators, no leading dots)."""
    base = _SAFE.sub("_", name.replace("\\", "/").split("/")[-1]).lstrip(".")
    return base[:200] or "file"


class Storage:
    def __init__(self, root: Path):
        self.root = Path(root)
        for sub in ("sets", "jobs", "tmp"):
            (self.root / sub).mkdir(parents=True, exist_ok=True)

    def set_dir(self, set_id: str) -> Path:
        return self.root / "sets" / set_id

    def images_dir(self, set_id: str) -> Path:
        return self.set_dir(set_id) / "images"

    def observations_path(self, set_id: str) -> Path:
        return self.set_dir(set_id) / "observations.json"

    def skipped_path(self, set_id: str) -> Path:
        """The upload's files that were not used, with why (backend/app/uploads.py)."""
        return self.set_dir(set_id) / "skipped.json"

    def board_suggestion_path(self, set_id: str) -> Path:
        """The board size the photos show, when it is not the set's (backend/queue/detect_job.py)."""
        return self.set_dir(set_id) / "board_suggestion.json"

    def rig_camera_path(self, job_id: str, k: int) -> Path:
        """A rig job's copy of camera ``k``'s corners, taken when the job was created."""
        return self.job_dir(job_id) / f"camera-{k}.json"

    def job_dir(self, job_id: str) -> Path:
        return self.root / "jobs" / job_id

    def tmp_dir(self) -> Path:
        return self.root / "tmp"

    def remove_set(self, set_id: str) -> None:
        shutil.rmtree(self.set_dir(set_id), ignore_errors=True)

    def remove_job(self, job_id: str) -> None:
        shutil.rmtree(self.job_dir(job_id), ignore_errors=True)


def write_bytes(path: Path, data: bytes) -> None:
    with _atomic(path) as f:
        f.write(data)


def write_text(path: Path, text: str) -> None:
    write_bytes(path, text.encode("utf-8"))


def write_json(path: Path, doc: Any, indent: int | None = None) -> None:
    write_bytes(path, json.dumps(doc, indent=indent, allow_nan=False, separators=None if indent else (",", ":"))
                .encode("utf-8"))


def write_cache(path: Path, data: bytes) -> bytes:
    """Keep ``data`` at ``path`` for the next reader (a thumbnail, a preview) when the data directory takes
    writes, and return it either way: a full or read-only disk must not turn a read into an error."""
    try:
        write_bytes(path, data)
    except OSError as exc:
        if exc.errno not in NO_SPACE + READ_ONLY:
            raise
    return data


def copy_stream(src: IO[bytes], path: Path, limit: int) -> int:
    """Copy a stream to ``path`` atomically; raises TooLarge past ``limit`` bytes."""
    n = 0
    with _atomic(path) as f:
        while chunk := src.read(CHUNK):
            n += len(chunk)
            if n > limit:
                raise TooLarge(path.name)
            f.write(chunk)
    return n


class _atomic:
    """Context manager: a temp file beside ``path`` that replaces it on success."""

    def __init__(self, path: Path):
        self.path = Path(path)

    def __enter__(self) -> BinaryIO:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, self.tmp = tempfile.mkstemp(dir=self.path.parent, prefix=".tmp-")
        self.f = os.fdopen(fd, "wb")
        return self.f

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if exc_type is None:
                self.f.flush()
                os.fsync(self.f.fileno())
            self.f.close()
            if exc_type is None:
                os.chmod(self.tmp, 0o644)  # readable by other containers sharing the volume
                os.replace(self.tmp, self.path)
        finally:
            if os.path.exists(self.tmp):
                os.unlink(self.tmp)


# ---- what a failed write means, in words the client can act on ------------------
DISK_FULL_ANSWER = "the server's disk is full: nothing was stored; free space in its data directory (or ask its " \
            "administrator to) and retry"
READ_ONLY_ANSWER = "the server cannot write its data directory (read-only or no permission): nothing was stored; " \
            "ask its administrator to make FREECAL_DATA_DIR writable, then retry"


def storage_failure(exc: BaseException) -> tuple[int, str] | None:
    """(status, message) when ``exc`` means the data directory cannot take writes, else None."""
    if isinstance(exc, OSError):
        if exc.errno in NO_SPACE:
            return 507, DISK_FULL_ANSWER
        if exc.errno in READ_ONLY:
            return 503, READ_ONLY_ANSWER
    if isinstance(exc, sqlite3.OperationalError):
        text = str(exc).lower()
        if "disk is full" in text or "disk i/o" in text:
            return 507, DISK_FULL_ANSWER
        if "readonly" in text or "read-only" in text or "unable to open" in text:
            return 503, READ_ONLY_ANSWER
    return None

"""What every part of the service shares: settings, the metadata store, the files."""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from calib_core.errors import SettingsError

from .db import Database
from .settings import Settings
from .storage import Storage


@dataclass(frozen=True)
class Context:
    settings: Settings
    db: Database
    storage: Storage

    @staticmethod
    def check_writable(data_dir: Path) -> None:
        """SettingsError (one line at the command line) when the data directory cannot take files."""
        try:
            data_dir.mkdir(parents=True, exist_ok=True)
            probe = data_dir / f".write-test-{os.getpid()}"
            probe.write_bytes(b"ok")
            probe.unlink()
        except OSError as exc:
            raise SettingsError(f"the data directory {data_dir} cannot be written ({exc.strerror or exc}): fix its "
                                "permissions or free space, or choose another with --data-dir / FREECAL_DATA_DIR") from None

    @classmethod
    def open(cls, settings: Settings) -> Context:
        settings.data_dir.mkdir(parents=True, exist_ok=True)
        return cls(settings, Database(settings.db_path), Storage(settings.data_dir))

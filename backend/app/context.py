"""What every part of the service shares: settings, the metadata store, the files."""
from __future__ import annotations

from dataclasses import dataclass

from .db import Database
from .settings import Settings
from .storage import Storage


@dataclass(frozen=True)
class Context:
    settings: Settings
    db: Database
    storage: Storage

    @classmethod
    def open(cls, settings: Settings) -> "Context":
        settings.data_dir.mkdir(parents=True, exist_ok=True)
        return cls(settings, Database(settings.db_path), Storage(settings.data_dir))

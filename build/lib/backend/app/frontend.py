"""The browser page: frontend/ served as plain static files at / (no build step).

The folder is found beside the package (a source checkout or editable
install) or at ``FREECAL_FRONTEND_DIR``; without it the API runs alone.
"""
from __future__ import annotations

import os
from pathlib import Path

from fastapi import FastAPI
from fastapi.staticfiles import StaticFiles

DEFAULT = Path(__file__).resolve().parents[2] / "frontend"


def mount(app: FastAPI) -> Path | None:
    """Serve the page at / (after every /api route, so those win); returns the folder, or None."""
    folder = Path(os.environ.get("FREECAL_FRONTEND_DIR") or DEFAULT)
    if not (folder / "index.html").is_file():
        return None
    app.mount("/", StaticFiles(directory=folder, html=True), name="frontend")
    return folder

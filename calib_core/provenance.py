"""Where a calibration came from, recorded in its JSON (``provenance``: an
extra field, which formats.md allows): the freecal version that made it, when
(UTC, ISO 8601), a hash of the observations it was fitted to, and the units
of the views' ``tvec`` (the board's: ``object_points`` are in them).

The hash is the SHA-256 of the observations as canonical JSON: freecal's
``Observations.to_json()`` dumped with sorted keys and no spaces
(``json.dumps(doc, sort_keys=True, separators=(",", ":"))``), so that the same
corners give the same hash whatever file layout carried them.
"""
from __future__ import annotations

import hashlib
import json
from datetime import UTC, datetime
from typing import Any

from .observations import Observations

UNKNOWN_UNITS = "the units of the observations' object_points"  # no board recorded (e.g. synthetic corners)


def freecal_version() -> str:
    """The installed package's version (``freecal --version``, reports, calibrations)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("freecal")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "unknown (not installed: pip install -e .)"


def observations_sha256(obs: Observations) -> str:
    """The SHA-256 (hex) of the observations' canonical JSON (module text)."""
    text = json.dumps(obs.to_json(), sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(text.encode("ascii")).hexdigest()


def provenance(obs: Observations) -> dict[str, Any]:
    """The ``provenance`` object of a calibration fitted to ``obs`` now."""
    units = (obs.board or {}).get("units")
    return {"freecal_version": freecal_version(),
            "created": datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z"),
            "observations_sha256": observations_sha256(obs),
            "tvec_units": str(units) if units else UNKNOWN_UNITS}

"""freecal's version (``freecal --version``, reports): the one the calibrations record."""
from __future__ import annotations

from calib_core.provenance import freecal_version as version

__all__ = ["version"]

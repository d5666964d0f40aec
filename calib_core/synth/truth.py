"""The synthetic lenses' ground truth as a ``CameraModel`` (``synth.true_project``),
so that every tool that takes a calibration (rectification, quality metrics,
lean fits) can be run on the truth for reference.

Only projection is needed: the Jacobian in ``xn`` is by central differences
(accurate to ~1e-7 relative, plenty for Newton's inversion, which checks the
pixel error itself). It has no parameters and is never fitted.
"""
from __future__ import annotations

from typing import Any, Self

import numpy as np

from .. import synth
from ..calibration import Calibration
from ..errors import FormatError
from ..models import camera
from ..models.base import CameraModel

STEP = 1e-6  # normalised units: ~3e-4 px at f ≈ 300


class TruthModel(CameraModel):
    kind = "synth-truth"

    def __init__(self, kind: str):
        if kind not in synth.ALL_KINDS:
            raise ValueError(f"unknown synthetic kind {kind!r}; expected one of {synth.ALL_KINDS}")
        self.lens = kind
        fx, fy, cx, cy = synth.INTRINSICS
        self.intrinsics = np.array([fx, fy, cx, cy, 0.0])
        # A lens past 180° is reached through angles: its normalised coordinates are equidistant ones.
        self.base = "equidistant" if kind in synth.WIDE_KINDS else "pinhole"

    @property
    def n_params(self) -> int:
        return 0

    def params(self) -> np.ndarray:
        return np.zeros(0)

    def with_params(self, x: np.ndarray) -> Self:
        return self  # the truth has nothing to fit

    def _uv(self, xn: np.ndarray) -> np.ndarray:
        return synth.true_project(self.lens, camera.ray_of(xn, self.base))

    def pixel_of(self, xn: np.ndarray, jacobian: bool = False):
        uv = self._uv(xn)
        if not jacobian:
            return uv
        d = np.empty((len(xn), 2, 2))
        for k in range(2):  # two columns, each evaluated vectorised over all points
            e = np.zeros(2)
            e[k] = STEP
            d[:, :, k] = (self._uv(xn + e) - self._uv(xn - e)) / (2 * STEP)
        # Newton (base.py) solves with this matrix: keep it invertible where the
        # lens folds over or overflows, so such points fail by their pixel error.
        det = d[:, 0, 0] * d[:, 1, 1] - d[:, 0, 1] * d[:, 1, 0]
        bad = ~np.isfinite(det) | (np.abs(det) < 1e-12)
        d[bad] = np.diag(self.intrinsics[:2])
        empty = np.zeros((len(xn), 2, 0))
        return uv, d, empty.astype(np.int64), empty

    def distortion_json(self) -> dict[str, Any]:
        return {"type": self.kind, "lens": self.lens}

    @classmethod
    def from_json(cls, intrinsics: np.ndarray, distortion: dict[str, Any], base: str) -> Self:
        """The truth back from its ``distortion_json`` (the intrinsics are the lens's own)."""
        if distortion.get("lens") not in synth.ALL_KINDS:
            raise FormatError(f"distortion.lens: expected one of {synth.ALL_KINDS}, got {distortion.get('lens')!r}")
        return cls(distortion["lens"])


def truth_calibration(kind: str) -> Calibration:
    """A ``Calibration`` whose model is the synthetic lens ``kind`` itself."""
    return Calibration(TruthModel(kind), synth.IMAGE_SIZE, "truth")

"""Kannala–Brandt (``fisheye``): θd = θ (1 + k1 θ² + … + kn θ^(2n)).

n = 4 is cv2.fisheye's model (a 9th-order angular polynomial, the paper's
BabelCalib baseline). The project's initialisation already is a KB camera:
this method refines it with every parameter free until converged.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .. import ranges
from ..errors import DataError
from ..fitting.init import initialise
from ..fitting.solve import Data, SolveSettings, levenberg_marquardt
from ..models.fisheye import FisheyeModel
from .common import Fit, Progress


@dataclass
class FisheyeSettings:
    n_coefficients: int = 4
    max_iterations: int = 500
    ftol: float = 1e-12

    def validate(self) -> None:
        ranges.whole("n_coefficients", self.n_coefficients, 1, 8)  # 4: cv2.fisheye's model
        ranges.iterations_and_tolerance(self.max_iterations, self.ftol)


def fit_fisheye(data: Data, image_size: tuple[int, int], s: FisheyeSettings, progress: Progress) -> Fit[FisheyeModel]:
    progress("initialise", 0.0)
    init = initialise(data, image_size, n_coefficients=s.n_coefficients)
    progress("levenberg-marquardt", 0.3)
    res = levenberg_marquardt(init.model, init.poses, data, SolveSettings(s.max_iterations, s.ftol))
    if not np.all(np.isfinite(res.residuals)):
        raise DataError("the Kannala–Brandt model diverged on these corners (non-finite projections)")
    diagnostics = {"initialisation": {"focal_source": init.focal_source, "rmse": init.rmse}}
    return Fit(res, np.zeros(data.n_points, dtype=bool), "", dataclasses.asdict(s), diagnostics)

"""OpenCV's models as methods: ``zhang`` (k1 k2 p1 p2 k3) and ``rational``
(k1 … k6), fitted by our sparse LM from the project's initialisation.

initialise() gives a Kannala–Brandt camera and poses with no focal guess
(works at any field of view); the OpenCV coefficients are then seeded by a
linear least-squares fit to the observed normalised distortion under those
poses, and everything is refined jointly.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .. import ranges
from ..errors import DataError, SettingsError
from ..fitting.init import initialise
from ..fitting.solve import Data, SolveResult, SolveSettings, levenberg_marquardt
from ..models import camera
from ..models.opencv import ALLOWED_COUNTS, OpenCVModel
from .common import Fit, Progress

# A pinhole model maps a ray θ off axis to tan θ: past this angle it cannot
# represent the corner (formats.md: the opencv type is pinhole-based).
MAX_ANGLE_DEG = camera.PINHOLE_MAX_ANGLE_DEG


@dataclass
class OpenCVSettings:
    n_coefficients: int = 5  # 4, 5, 8, 12 or 14 (OpenCV's prefixes)
    max_iterations: int = 500
    ftol: float = 1e-12  # parametric problems are small: converge fully (cv2 agreement to 1e-6 px)

    def validate(self) -> None:
        if self.n_coefficients not in ALLOWED_COUNTS:
            raise SettingsError(f"n_coefficients: OpenCV takes {ALLOWED_COUNTS}, got {self.n_coefficients}")
        ranges.iterations_and_tolerance(self.max_iterations, self.ftol)


@dataclass
class RationalSettings(OpenCVSettings):
    n_coefficients: int = 8


def seed_coefficients(xn: np.ndarray, xd: np.ndarray, n: int) -> np.ndarray:
    """Linear least-squares OpenCV coefficients (n,) mapping ``xn`` (N, 2) to ``xd`` (N, 2).

    The rational denominator is linearised (xd·den = x·num + tangential), which
    is exact when the tangential and prism terms vanish."""
    x, y = xn[:, 0], xn[:, 1]
    r2 = x * x + y * y
    cols = {  # column of each coefficient for the x rows and the y rows
        0: (x * r2, y * r2), 1: (x * r2**2, y * r2**2), 2: (2 * x * y, r2 + 2 * y * y),
        3: (r2 + 2 * x * x, 2 * x * y), 4: (x * r2**3, y * r2**3),
        5: (-xd[:, 0] * r2, -xd[:, 1] * r2), 6: (-xd[:, 0] * r2**2, -xd[:, 1] * r2**2),
        7: (-xd[:, 0] * r2**3, -xd[:, 1] * r2**3),
        8: (r2, 0 * r2), 9: (r2**2, 0 * r2), 10: (0 * r2, r2), 11: (0 * r2, r2**2),
    }
    m = min(n, 12)
    a = np.vstack([np.column_stack([cols[k][0] for k in range(m)]), np.column_stack([cols[k][1] for k in range(m)])])
    b = np.concatenate([xd[:, 0] - x, xd[:, 1] - y])
    scale = np.linalg.norm(a, axis=0)
    scale[scale == 0] = 1.0
    sol = np.linalg.lstsq(a / scale, b, rcond=None)[0] / scale
    out = np.zeros(n)
    out[:m] = sol
    return out


def pinhole_visible(poses: np.ndarray, data: Data) -> np.ndarray:
    """(N,) bool: corners less than MAX_ANGLE_DEG off axis under ``poses``."""
    pc = camera.transform(poses, data.view_index, data.object_points)
    return pc[:, 2] / np.linalg.norm(pc, axis=1) > np.cos(np.radians(MAX_ANGLE_DEG))


RACE_ITERATIONS = 25


def best_of(starts: list[tuple[OpenCVModel, np.ndarray]], data: Data, settings: SolveSettings) -> SolveResult[OpenCVModel]:
    """The best converged fit from several (model, poses) starts. Each runs
    RACE_ITERATIONS first; only the lowest then runs to convergence. A start
    headed for a worse minimum shows it early (measured on the rational model:
    2.5x the leader's cost after 25 iterations), and crawling there to
    ftol = 1e-12 cost up to 500 iterations."""
    short = dataclasses.replace(settings, max_iterations=min(RACE_ITERATIONS, settings.max_iterations))
    raced = [levenberg_marquardt(model, poses, data, short) for model, poses in starts]
    leader = min(raced, key=lambda r: r.cost)
    if leader.status == "max_iterations" and settings.max_iterations > RACE_ITERATIONS:
        rest = dataclasses.replace(settings, max_iterations=settings.max_iterations - leader.iterations)
        finished = levenberg_marquardt(leader.model, leader.poses, data, rest)
        finished.iterations += leader.iterations
        leader = finished
    return leader


def fit_opencv(data: Data, image_size: tuple[int, int], s: OpenCVSettings, progress: Progress,
               five: Fit[OpenCVModel] | None = None) -> Fit[OpenCVModel]:
    """OpenCV's model with ``s.n_coefficients``, converged from several starts;
    ``five``: the 5-coefficient fit of the same corners, if already made (a
    start of the larger models)."""
    progress("initialise", 0.0)
    init = initialise(data, image_size)
    ok = pinhole_visible(init.poses, data)
    if ok.sum() < 0.5 * len(ok):
        raise DataError(
            f"most corners lie more than {MAX_ANGLE_DEG:.0f}° off axis, where OpenCV's pinhole-based model "
            "cannot represent them: use --method fisheye or bspline with --base equidistant"
        )
    sub = data.points(ok)
    fx, fy, cx, cy, _ = init.model.intrinsics
    pc = camera.transform(init.poses, sub.view_index, sub.object_points)
    xn = pc[:, :2] / pc[:, 2:]
    xd = (sub.image_points - [cx, cy]) / [fx, fy]
    progress("levenberg-marquardt", 0.2)
    settings = SolveSettings(s.max_iterations, s.ftol)

    def start(coefficients: np.ndarray) -> tuple[OpenCVModel, np.ndarray]:
        return OpenCVModel([fx, fy, cx, cy, 0.0], coefficients), init.poses

    def first_starts(n: int) -> list[tuple[OpenCVModel, np.ndarray]]:
        # The linear seed, and no distortion: the seed can be poor at wide angles (a polynomial
        # in r² far out).
        return [start(seed_coefficients(xn, xd, n)), start(np.zeros(n))]

    if s.n_coefficients <= 5:
        starts = first_starts(s.n_coefficients)
    else:
        # Nested models start from the best 5-coefficient fit, so that rational is never worse
        # than zhang on the same corners, and from no distortion. Their own linear seed is not
        # raced: its few deeper minima (under 0.5 % of the cost) predicted new views worse
        # (docs/model-choice.md, "The rational model's starts").
        nested = five.result if five is not None and np.array_equal(five.excluded, ~ok) else best_of(
            first_starts(5), sub, settings)
        k = np.zeros(s.n_coefficients)
        k[:5] = nested.model.coefficients
        starts = [(OpenCVModel(nested.model.intrinsics, k), nested.poses), start(np.zeros(s.n_coefficients))]
    res = best_of(starts, sub, settings)
    if not np.all(np.isfinite(res.residuals)):
        raise DataError("the OpenCV model diverged on these corners (non-finite projections); "
                        "the lens is probably too wide for it: use --method fisheye or bspline")
    diagnostics = {"initialisation": {"focal_source": init.focal_source, "model": "kannala-brandt (4)", "rmse": init.rmse}}
    return Fit(res, ~ok, f"more than {MAX_ANGLE_DEG:.0f}° off axis (outside the pinhole model)",
               dataclasses.asdict(s), diagnostics)

"""The solver's ways of ending, on a toy problem small enough to reason about:
a 5-coefficient camera and three views of a 6 × 5 board, noise-free."""
from __future__ import annotations

import numpy as np
import pytest

from calib_core.fitting.solve import Cancelled, Data, SolveSettings, levenberg_marquardt
from calib_core.models import camera
from calib_core.models.opencv import OpenCVModel

TRUE = OpenCVModel([800.0, 790.0, 320.0, 240.0, 0.0], [-0.2, 0.05, 0.001, -0.002, 0.0])
POSES = np.array([[0.2, -0.1, 0.05, -60.0, -40.0, 500.0],
                  [-0.3, 0.2, -0.1, -50.0, -45.0, 550.0],
                  [0.1, 0.35, 0.2, -70.0, -35.0, 480.0]])


def toy() -> Data:
    j, i = np.meshgrid(np.arange(5), np.arange(6), indexing="ij")
    board = np.stack([i.ravel() * 25.0, j.ravel() * 25.0, np.zeros(30)], axis=-1)
    obj = np.tile(board, (3, 1))
    view = np.repeat(np.arange(3), 30)
    uv = TRUE.project(camera.transform(POSES, view, obj))
    return Data(obj, uv, view, 3)


def start() -> OpenCVModel:
    return OpenCVModel([760.0, 760.0, 330.0, 250.0, 0.0], [0.0, 0.0, 0.0, 0.0, 0.0])


def test_from_a_nearby_start_it_converges_to_the_truth():
    res = levenberg_marquardt(start(), POSES + 0.01, toy(), SolveSettings(ftol=1e-12, xtol=1e-12))
    assert res.status in ("converged", "stalled")
    assert np.allclose(res.model.intrinsics[:4], TRUE.intrinsics[:4], atol=1e-4)
    assert np.max(np.abs(res.residuals)) < 1e-6


def test_an_iteration_cap_stops_it_and_says_so():
    res = levenberg_marquardt(start(), POSES + 0.01, toy(), SolveSettings(max_iterations=2))
    assert res.status == "max_iterations" and res.iterations == 2
    assert "2 iterations" in res.message


def test_at_the_minimum_already_nothing_moves_and_it_stops_at_once():
    res = levenberg_marquardt(TRUE, POSES, toy(), SolveSettings())
    assert res.status in ("converged", "stalled") and res.iterations <= 2
    assert np.allclose(res.model.params(), TRUE.params(), atol=1e-9)


def test_a_callback_that_cancels_ends_the_solve_after_that_step():
    seen = []

    def cancel(iteration: int, cost: float) -> None:
        seen.append(cost)
        raise Cancelled("user asked")

    with pytest.raises(Cancelled):
        levenberg_marquardt(start(), POSES + 0.01, toy(), SolveSettings(), callback=cancel)
    assert len(seen) == 1


def test_a_held_model_refits_only_the_poses():
    res = levenberg_marquardt(TRUE, POSES + 0.02, toy(), SolveSettings(fix_model=True, ftol=1e-12))
    assert np.array_equal(res.model.params(), TRUE.params())
    assert np.allclose(res.poses, POSES, atol=1e-6)

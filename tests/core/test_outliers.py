"""Gross corner errors (a misdetected corner, a corner snapped to the wrong
saddle) are found, reported per view and kept out of the calibration."""
import copy

import pytest

from calib_core import calibrate
from calib_core.evaluation.evaluate import evaluate

from ..conftest import synthetic

# (view, corner index, pixel error): a few corners far off, as a detector's slips are.
SLIPS = [(0, 5, (12.0, 0.0)), (3, 40, (0.0, -9.0)), (6, 100, (7.0, 7.0)), (9, 17, (-15.0, 4.0))]


def sets(kind: str):
    """The clean synthetic set and a copy with SLIPS (the cached set stays clean)."""
    clean = synthetic(kind)
    slipped = copy.deepcopy(clean)
    for view, corner, error in SLIPS:
        slipped.train.views[view].image_points[corner] += error
    return clean, slipped


# Each method on a lens it represents: elsewhere its misfit is structured,
# and the robust test rightly flags the corners it cannot fit.
@pytest.mark.slow
@pytest.mark.parametrize("method, kind", [("bspline", "asymmetric"), ("rational", "radial")])
def test_slipped_corners_are_rejected_and_cost_nothing(method, kind):
    clean, slipped = sets(kind)
    cal = calibrate(slipped.train, method)
    for view, corner, _ in SLIPS:
        assert corner in cal.views[view].outliers, (view, corner)
    # A 5-sigma test on 2 250 Gaussian corners flags almost no good one.
    assert cal.diagnostics.excluded_points.outliers <= len(SLIPS) + 3
    reference = evaluate(calibrate(clean.train, method), clean.holdout)["rmse"]
    assert evaluate(cal, slipped.holdout)["rmse"] <= 1.05 * reference + 1e-3


def test_the_refit_without_them_starts_at_the_minimum():
    """After the outliers go, the field's refit converges in a few steps: it
    takes the final fit's Gauss-Newton trials, not damped steps that crawl
    along the field's flat valley (13 iterations against 3 on BabelCalib)."""
    cal = calibrate(sets("asymmetric")[1].train, "bspline", core="none")
    solver = cal.diagnostics.solver
    assert solver.status == "converged"
    assert solver.iterations <= 5

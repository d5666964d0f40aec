"""The ± of each parameter in the report (calib_core/evaluation/parameters.py) is the
spread a user would see calibrating again: measured by re-noising the same views."""
from __future__ import annotations

import numpy as np
import pytest

from calib_core import calibrate
from calib_core.evaluation.parameters import parameter_names, parameter_table
from calib_core.observations import Observations, View

from ..conftest import synthetic


@pytest.mark.slow
def test_standard_deviations_match_the_spread_of_recalibrations():
    s = synthetic("radial")
    cal = calibrate(s.train, "zhang", outlier_sigma=0)
    table = parameter_table(cal, s.train)
    assert [r["name"] for r in table["rows"]] == ["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"]
    predicted = np.array([r["std"] for r in table["rows"]])
    rng = np.random.default_rng(0)
    again = []
    for _ in range(20):  # the fitted projections of the same views, with new noise of the estimated sigma
        views = []
        for v in s.train.views:
            fit = cal.view(v.name)
            clean = cal.project(v.object_points, fit.rvec, fit.tvec)
            views.append(View(v.name, v.object_points, clean + rng.normal(0, table["sigma"], clean.shape), v.ids))
        again.append(calibrate(Observations(s.train.image_size, views, s.train.board), "zhang",
                               outlier_sigma=0).model.params())
    spread = np.std(again, axis=0, ddof=1)
    # 20 draws: the spread itself is known to ~16 %; measured ratios 0.8-1.3
    assert np.all((spread / predicted > 0.6) & (spread / predicted < 1.6)), spread / predicted


def test_held_parameters_and_the_field_are_named():
    cal = calibrate(synthetic("radial").train, "bspline", intervals=4, core="rational")
    names = parameter_names(cal.model)
    assert names[:4] == ["fx", "fy", "cx", "cy"] and names[4] == "k1" and names[-1] == "field"
    table = parameter_table(cal, synthetic("radial").train)
    rows = {r["name"]: r for r in table["rows"]}
    assert rows["k1"]["held"] and rows["k1"]["std"] is None  # the hybrid holds its core's coefficients
    assert rows["fx"]["std"] > 0 and table["field"]["std_median"] > 0
    alone = parameter_table(cal, None)
    assert alone["sigma"] is None and all(r["std"] is None for r in alone["rows"])

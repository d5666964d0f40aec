"""Property-based tests (hypothesis) of what reads untrusted input.

The JSON readers face uploads: whatever JSON value arrives, they either parse
it or raise FormatError (which the API turns into a 422 and the CLI into one
line) — never a TypeError, OverflowError or KeyError that would be a 500.
The knot strategy faces whatever corners a user's images give: any point
cloud yields sorted breaks spanning the domain whose regularised design has
full column rank (the solver's linear system is never singular), or a
SettingsError saying what to change.
"""
from __future__ import annotations

import copy

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from calib_core import Calibration, Observations
from calib_core.errors import CalibError, FormatError, SettingsError
from calib_core.fitting import knots
from calib_core.models.bspline_basis import BSplineField, clamped_knots

from ..conftest import synthetic

FAST = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])

# Any JSON value, with the numbers a hostile client can send (huge ints; Python's json reads NaN/Infinity too).
scalars = (st.none() | st.booleans() | st.integers() | st.integers(min_value=10**300, max_value=10**400)
           | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=8))
json_values = st.recursive(scalars, lambda kids: st.lists(kids, max_size=4)
                           | st.dictionaries(st.text(max_size=8), kids, max_size=4), max_leaves=20)


def _small_observations() -> dict:
    doc = synthetic("radial").train.to_json()
    doc["views"] = [{k: (x[:5] if isinstance(x, list) else x) for k, x in v.items()} for v in doc["views"][:3]]
    Observations.from_json(doc)  # the starting point is valid
    return doc


OBS = _small_observations()
CAL = None


def _calibration_doc() -> dict:
    global CAL
    if CAL is None:
        from calib_core import calibrate

        CAL = calibrate(synthetic("radial").train, "zhang").to_json()
    return CAL


def _paths(doc, prefix=()):
    """Every (path, value) inside a JSON document."""
    yield prefix, doc
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc[:3]):  # the first few items of long lists are enough
            yield from _paths(v, prefix + (i,))


def _mutate(doc, data) -> dict:
    """``doc`` with one field (anywhere) replaced by any JSON value, or deleted."""
    doc = copy.deepcopy(doc)
    paths = [p for p, _ in _paths(doc) if p]
    path = data.draw(st.sampled_from(paths))
    parent = doc
    for key in path[:-1]:
        parent = parent[key]
    if data.draw(st.booleans()) and isinstance(parent, dict):
        del parent[path[-1]]
    else:
        parent[path[-1]] = data.draw(json_values)
    return doc


def _parses_or_format_error(reader, doc) -> None:
    try:
        reader(doc)
    except FormatError as exc:
        assert str(exc), "a FormatError must say what is wrong"


@pytest.mark.slow
@FAST
@given(json_values)
def test_observations_reader_takes_any_json_value(doc):
    _parses_or_format_error(Observations.from_json, doc)


@FAST
@given(st.data())
def test_observations_reader_takes_any_corruption_of_a_valid_document(data):
    _parses_or_format_error(Observations.from_json, _mutate(OBS, data))


@FAST
@given(json_values)
def test_calibration_reader_takes_any_json_value(doc):
    _parses_or_format_error(Calibration.from_json, doc)


@FAST
@given(st.data())
def test_calibration_reader_takes_any_corruption_of_a_valid_document(data):
    _parses_or_format_error(Calibration.from_json, _mutate(_calibration_doc(), data))


def test_readers_name_the_field_of_known_bad_values():
    """The messages a user sees for the classic mistakes (and that NaN never gets through)."""
    bad = copy.deepcopy(OBS)
    bad["views"][0]["image_points"][0] = [float("nan"), 1.0]
    with pytest.raises(FormatError, match=r"image_points\[0\].*not finite"):
        Observations.from_json(bad)
    bad = copy.deepcopy(OBS)
    bad["image_size"] = [10**400, 480]
    with pytest.raises(FormatError, match="image_size"):
        Observations.from_json(bad)
    bad = copy.deepcopy(OBS)
    bad["views"][1]["image_points"][2] = [1e12, 5.0]
    with pytest.raises(FormatError, match=r"image_points\[2\].*far outside"):
        Observations.from_json(bad)
    cal = copy.deepcopy(_calibration_doc())
    cal["metrics"] = [1]
    with pytest.raises(FormatError, match="metrics"):
        Calibration.from_json(cal)


# ---- knots -----------------------------------------------------------------------------
DOMAIN = (-50.0, 690.0, -40.0, 520.0)
clouds = arrays(np.float64, st.tuples(st.integers(1, 300), st.just(2)),
                elements=st.floats(0.0, 1.0, allow_nan=False, width=32))
strategies = st.sampled_from(["kde", "kde-paper", "uniform"])


@pytest.mark.slow
@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(clouds, strategies, st.integers(-2, 20), st.integers(-2, 20), st.floats(0.0, 1.0), st.integers(0, 3))
@example(np.array([[1.0, 1.0]]), "kde", 1, 1, 0.9999999999999999, 0)  # a corner 1e-13 from the domain's end
def test_any_point_cloud_gives_a_full_rank_design_or_a_settings_error(unit, strategy, nu, nv, squash, clusters):
    # corners anywhere in the domain, possibly squashed onto a line or a few points (degenerate clouds)
    u0, u1, v0, v1 = DOMAIN
    pts = np.column_stack([u0 + unit[:, 0] * (u1 - u0), v0 + unit[:, 1] * (v1 - v0) * squash])
    if clusters:
        pts = np.round(pts / (200.0 * clusters)) * 200.0 * clusters
        pts = np.clip(pts, [u0, v0], [u1, v1])
    weights = np.ones_like(pts)
    s = knots.KnotSettings(strategy=strategy, intervals=(nu, nv))
    try:
        s.validate()
        bu, bv = knots.breaks_for(pts, weights, DOMAIN, s)
    except SettingsError as exc:
        assert "interval" in str(exc)
        assert min(nu, nv) < 1
        return
    for b, lo, hi in ((bu, u0, u1), (bv, v0, v1)):
        assert np.all(np.isfinite(b)) and b[0] == lo and b[-1] == hi
        assert np.all(np.diff(b) > 0), "breaks must increase strictly (a zero-width interval is singular)"
    field = BSplineField.zeros(clamped_knots(bu), clamped_knots(bv))
    design = field.design(pts).matrix(field.n_controls).toarray()
    # the fit solves [B; sqrt(lambda_reg) I; sqrt(lambda) D] (bspline.py): full column rank
    lam_reg = 1e-6  # the smallest regularisation the method uses by default is larger
    system = np.vstack([design, np.sqrt(lam_reg) * np.eye(field.n_controls), field.bending().toarray()])
    assert np.linalg.matrix_rank(system) == field.n_controls
    assert np.all(np.isfinite(design)) and np.allclose(design.sum(axis=1), 1.0)  # partition of unity


@pytest.mark.slow
@settings(max_examples=60, deadline=None)
@given(st.sampled_from(["kde", "kde-paper"]), clouds)
def test_adaptive_knots_leave_no_observed_cell_empty(strategy, unit):
    """The paper's coverage rule: every knot cell the corners span holds a corner (or merging ran out)."""
    assume(len(unit) >= 30)
    u0, u1, v0, v1 = DOMAIN
    pts = np.column_stack([u0 + unit[:, 0] * (u1 - u0), v0 + unit[:, 1] * (v1 - v0)])
    s = knots.KnotSettings(strategy=strategy, coverage_rounds=200)
    bu, bv = knots.breaks_for(pts, np.ones_like(pts), DOMAIN, s, footprint=None)
    counts = np.histogram(pts[:, 0], bins=bu)[0]
    assert counts.sum() == len(pts)
    assert len(bu) >= 2 and len(bv) >= 2


def test_calib_errors_are_one_family():
    """What the API maps to 4xx: every user error class derives from CalibError."""
    assert issubclass(FormatError, CalibError) and issubclass(SettingsError, CalibError)

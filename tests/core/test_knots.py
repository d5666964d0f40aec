"""The adaptive knot steps of method.md §"Adaptive knots", one by one."""
import numpy as np
import pytest

from calib_core.errors import SettingsError
from calib_core.fitting import knots


def test_local_std_weights_are_high_where_the_response_varies():
    d = np.linspace(0, 1000, 1000)
    z = np.where(d > 700, np.sin(d / 5.0) * 10, 0.1 * d / 1000)  # smooth, then wiggly
    w = knots.local_std_weights(d, z, knots.KnotSettings())
    assert w.min() == pytest.approx(0.5) and w.max() == pytest.approx(1.5)
    assert w[d > 750].mean() > 1.2 > 0.6 > w[d < 650].mean()


def test_constant_response_gives_unit_weights():
    d = np.random.default_rng(0).uniform(0, 10, 200)
    assert np.all(knots.local_std_weights(d, np.full(200, 3.0), knots.KnotSettings()) == 1.0)


def test_scott_bandwidth_and_factor():
    d = np.random.default_rng(1).normal(0, 100, 2000)
    w = np.ones_like(d)
    h = knots.bandwidth(d, w, knots.KnotSettings())
    assert h == pytest.approx(np.std(d) * 2000 ** (-1 / 5), rel=1e-6)
    assert knots.bandwidth(d, w, knots.KnotSettings(bandwidth_factor=1.2)) == pytest.approx(1.2 * h)


def test_kde_maxima_find_the_modes():
    rng = np.random.default_rng(2)
    d = np.concatenate([rng.normal(200, 20, 500), rng.normal(700, 20, 500)])
    peaks = knots.kde_maxima(d, np.ones_like(d), 30.0)
    assert len(peaks) == 2 and abs(peaks[0] - 200) < 10 and abs(peaks[1] - 700) < 10


def test_support_merging_and_cap():
    d = np.concatenate([np.linspace(0, 100, 500), [950.0]])  # one lonely sample far right
    breaks = np.array([0, 10, 20, 30, 40, 50, 60, 70, 80, 90, 100, 500, 1000.0])
    out = knots.merge_for_support(d, breaks, n_min=20, max_intervals=6)
    counts = np.histogram(d, bins=out)[0]
    assert len(counts) <= 6 and counts.min() >= 20
    assert out[0] == 0 and out[-1] == 1000  # the domain ends stay


@pytest.mark.slow
def test_coverage_merge_empties_no_seen_cell():
    rng = np.random.default_rng(3)
    pts = rng.uniform(0, 100, (400, 2))
    pts = pts[~((pts[:, 0] > 40) & (pts[:, 0] < 60) & (pts[:, 1] > 40) & (pts[:, 1] < 60))]  # a hole
    bu = bv = np.linspace(0, 100, 11)
    nu, nv = knots.coverage_merge(pts, bu, bv, rounds=30)
    hist = np.histogram2d(pts[:, 0], pts[:, 1], bins=[nu, nv])[0]
    assert hist.min() > 0 and (len(nu) < 11 or len(nv) < 11)


def test_kde_strategy_gives_more_intervals_than_the_papers_candidates():
    rng = np.random.default_rng(4)
    samples = rng.normal([500, 600], [200, 250], (2000, 2))
    w = np.ones((2000, 2))
    domain = (-200, 1200, -200, 1400)
    paper = knots.adaptive_breaks(samples, w, domain, knots.KnotSettings(strategy="kde-paper"))
    ours = knots.adaptive_breaks(samples, w, domain, knots.KnotSettings(strategy="kde", intervals=(10, 10)))
    assert len(ours[0]) > len(paper[0]) and len(ours[0]) - 1 <= 10
    for b in ours:
        assert b[0] in (-200, 1200, -200) and np.all(np.diff(b) > 0)


def test_unknown_strategy_is_a_settings_error():
    with pytest.raises(SettingsError, match="strategy"):
        knots.KnotSettings(strategy="magic").validate()

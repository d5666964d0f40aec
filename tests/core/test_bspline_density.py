"""Knot density from the data: the search over knot grids and KDE bandwidth
factors by validation over views, where it stops, and how it is reported."""
import json

import pytest

from backend.cli import main
from calib_core import calibrate
from calib_core.errors import SettingsError
from calib_core.methods.bspline import AUTO_BANDWIDTH_FACTORS

from ..conftest import synthetic


def auto_bandwidth(**settings):
    return calibrate(synthetic("asymmetric").train, "bspline", core="none", bandwidth_factor="auto", **settings)


@pytest.fixture(scope="module")
def searched():
    return auto_bandwidth()


@pytest.mark.slow
def test_auto_bandwidth_picks_a_factor_and_records_the_curve(searched):
    chosen = searched.settings["bandwidth_factor_used"]
    assert chosen in AUTO_BANDWIDTH_FACTORS
    curve = searched.diagnostics.extra["smoothing_curve"]
    assert {c["bandwidth_factor"] for c in curve} == set(AUTO_BANDWIDTH_FACTORS)
    # Each factor scores its two coarsest grids at least; finer ones stop once
    # two in a row predicted no better than the best before them.
    for factor in AUTO_BANDWIDTH_FACTORS:
        entries = [c for c in curve if c["bandwidth_factor"] == factor]
        assert all("cv" in c for c in entries[:2])
        assert all(("cv" in c) != ("skipped" in c) for c in entries)
        assert all(c["skipped"] == "2 coarser grids predicted no better" for c in entries if "skipped" in c)
    # The grid kept is the one that predicted the left-out views best (its λ already prices its flexibility).
    scored = [c for c in curve if "validation" in c]
    best = min(scored, key=lambda c: c["validation"])
    assert [searched.settings["intervals_used"], chosen] == [best["intervals"], best["bandwidth_factor"]]


@pytest.mark.slow
def test_a_budget_that_is_not_reached_changes_nothing(searched):
    again = auto_bandwidth(time_budget=1e3)
    assert again.diagnostics.extra["smoothing_curve"] == searched.diagnostics.extra["smoothing_curve"]
    assert again.settings["bandwidth_factor_used"] == searched.settings["bandwidth_factor_used"]


def test_the_time_budget_stops_the_search_and_says_so():
    cal = auto_bandwidth(time_budget=1e-9)
    first, *rest = cal.diagnostics.extra["smoothing_curve"]
    assert "cv" in first  # the first candidate always runs
    assert rest and all(c["skipped"] == "time budget" and "cv" not in c for c in rest)
    assert [cal.settings["intervals_used"], cal.settings["bandwidth_factor_used"]] == [first["intervals"], 1.0]


@pytest.mark.parametrize("settings, message", [
    (dict(bandwidth_factor="wide"), "bandwidth_factor: expected 'auto' or a number above 0 and at most 100"),
    (dict(bandwidth_factor=0), "bandwidth_factor: expected 'auto' or a number above 0 and at most 100"),
    (dict(time_budget=0), r"time_budget \(seconds\): expected null \(no limit\) or a number above 0"),
    (dict(time_budget="fast"), r"time_budget \(seconds\): expected null \(no limit\) or a number above 0"),
])
def test_bad_bandwidth_or_budget_is_named(settings, message):
    with pytest.raises(SettingsError, match=message):
        calibrate(synthetic("radial").train, "bspline", **settings)


def test_cli_takes_auto_bandwidth_and_prints_the_curve(tmp_path, capsys):
    obs = tmp_path / "train.json"
    obs.write_text(json.dumps(synthetic("asymmetric").train.to_json()))
    assert main(["calibrate", str(obs), "-q", "--method", "bspline", "--core", "none", "--bandwidth-factor", "auto",
                 "--time-budget", "1e-9"]) == 0
    printed = capsys.readouterr().out
    assert "bandwidth factor" in printed and "skipped (time budget)" in printed
    with pytest.raises(SystemExit) as bad:  # argparse rejects it before anything runs
        main(["calibrate", str(obs), "-q", "--method", "bspline", "--bandwidth-factor", "wide"])
    assert bad.value.code == 2 and "--bandwidth-factor: expected a number or auto" in capsys.readouterr().err

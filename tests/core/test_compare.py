"""freecal compare: every method on the same corners, the JSON contract, the verdict."""
import json

import numpy as np
import pytest

from backend.cli import main as cli
from calib_core import synth
from calib_core.errors import DataError, SettingsError
from calib_core.evaluation.compare import compare, neighbour_correlation
from calib_core.observations import Observations
from calib_core.pipeline import calibrate


@pytest.fixture(scope="module")
def small():
    s = synth.generate("radial", sigma=0.3, seed=0, n_views=6)
    return s


@pytest.fixture(scope="module")
def result(small):
    hold = Observations(small.holdout.image_size, [v.subset(np.arange(len(v)) % 16 == 0) for v in small.holdout.views[:3]])
    return compare(small.train, ["zhang", "fisheye", "mls"], splits=3, holdout=hold)


@pytest.mark.slow
def test_compare_json_contract(result):
    doc = json.loads(json.dumps(result.to_json(), allow_nan=False))
    assert set(doc["methods"]) == {"zhang", "fisheye", "mls"}
    for entry in doc["methods"].values():
        for key in ("rmse", "rmse_axis", "holdout_rmse", "cv_validation_rmse", "rmse_center", "rmse_edge"):
            assert np.isfinite(entry[key])
        assert len(entry["cv"]["splits"]) == 3
        validated = sorted(n for s in entry["cv"]["splits"] for n in s["validated"])
        assert len(validated) == 6 and len(set(validated)) == 6  # each view validated once
    assert doc["verdict"] in doc["methods"] and doc["verdict"] == result.verdict


@pytest.mark.slow
def test_parametric_model_wins_on_its_own_lens(result):
    # The radial lens is OpenCV's model: zhang fits it to the noise, KB cannot.
    ms = result.scored
    assert ms["zhang"].cv_validation_rmse < ms["fisheye"].cv_validation_rmse
    assert ms["zhang"].fit.rmse < 0.3 * np.sqrt(2) * 1.1
    assert result.verdict in ("zhang", "mls")
    assert not result.verdict_detail["spatial_structure"]["structured"]


def test_neighbour_correlation_detects_a_smooth_error():
    g = np.stack(np.meshgrid(np.arange(20.0), np.arange(20.0)), -1).reshape(-1, 2)
    obj = np.column_stack([g * 10, np.zeros(len(g))])
    view = np.zeros(len(g), dtype=int)
    rng = np.random.default_rng(0)
    noise = rng.normal(size=(len(g), 2))
    smooth = np.column_stack([np.sin(g[:, 0] / 4), np.cos(g[:, 1] / 5)]) * 2
    assert neighbour_correlation(noise, obj, view)["p_value"] > 0.01
    s = neighbour_correlation(noise + smooth, obj, view)
    assert s["p_value"] < 0.01 and s["rho"] > 0.3


def test_bad_settings_say_what_to_do(small):
    with pytest.raises(SettingsError, match="unknown method"):
        compare(small.train, ["nope"])
    with pytest.raises(DataError, match="fewer splits"):
        compare(small.train.select([v.name for v in small.train.views[:4]]), ["zhang"], splits=2)


def test_cli_prints_one_json_object(tmp_path, small, capsys):
    path = tmp_path / "obs.json"
    small.train.save(path)
    assert cli(["compare", str(path), "--methods", "zhang", "--splits", "3", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["verdict"] == "zhang" and "cv_validation_rmse" in doc["methods"]["zhang"]
    assert cli(["compare", str(path), "--methods", "zhang", "--splits", "3", "-q"]) == 0
    text = capsys.readouterr().out
    assert "Verdict: zhang" in text and "Cross-validation" in text


@pytest.mark.slow
def test_on_opencvs_own_lens_the_default_and_the_verdict_both_name_zhang(small):
    """The radial lens is OpenCV's model: a field can only fit noise. The
    default (auto) returns OpenCV's model, and compare's verdict, by the same
    rule, names zhang over TPS (which adds a smoothed field to it) and over
    the paper's field, whatever order the methods were asked in."""
    result = compare(small.train, ["bspline", "auto", "tps", "zhang"], splits=3)
    cv = {m: r.cv_validation_rmse for m, r in result.scored.items()}
    assert cv["zhang"] < cv["tps"] and cv["zhang"] < cv["bspline"]
    assert result.verdict == "zhang"
    assert calibrate(small.train).settings["chosen"] == "zhang"
    choice = result.verdict_detail["model_choice"]
    assert choice["chosen"] == "zhang" and "one-standard-error rule" in choice["rule"]

"""freecal calibrate IMAGES --board SPEC: detect, report, then calibrate (real photos)."""
from __future__ import annotations

import json

import pytest

from backend.cli import main as cli
from tests.conftest import shared_data


@pytest.mark.slow  # detects real photos, then calibrates: seconds
def test_calibrate_from_images_detects_then_calibrates(tmp_path, capsys):
    root = shared_data("opencv-stereo-9x6")
    left = sorted(str(p) for p in root.glob("left*.jpg"))
    assert len(left) == 13
    out = tmp_path / "cal.json"
    assert cli(["calibrate", *left, "--board", "chessboard:9x6:1mm", "--method", "zhang", "-q", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "13/13 images used" in text          # the detection report comes first
    doc = json.loads(out.read_text())
    assert doc["format"] == "freecal.calibration/1" and doc["image_size"] == [640, 480]
    assert len(doc["views"]) == 13
    assert 0.05 < doc["metrics"]["rmse"] < 0.4, doc["metrics"]   # SOURCE.md: 0.235 px with OpenCV's own corners


def test_calibrate_from_images_needs_a_board(tmp_path, capsys):
    root = shared_data("opencv-stereo-9x6")
    assert cli(["calibrate", str(root), "--method", "zhang"]) == 2
    assert "--board SPEC" in capsys.readouterr().err
    assert cli(["calibrate", str(root / "left01.jpg"), "--board", "chessboard:9x6"]) == 2
    assert "COLSxROWS:SQUARE" in capsys.readouterr().err


@pytest.mark.slow  # detects real photos, then calibrates: seconds
def test_detect_refine_with_a_calibration_says_what_it_added(tmp_path, capsys):
    """freecal detect --refine-with CAL.json: corners predicted through a first calibration."""
    root = shared_data("opencv-stereo-9x6")
    left = sorted(str(p) for p in root.glob("left*.jpg"))
    cal = tmp_path / "cal.json"
    assert cli(["calibrate", *left, "--board", "chessboard:9x6:1mm", "--method", "zhang", "-q", "-o", str(cal)]) == 0
    capsys.readouterr()
    out = tmp_path / "obs.json"
    assert cli(["detect", *left, "--board", "chessboard:9x6:1mm", "--refine-with", str(cal), "-q", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "13/13 images used" in text
    assert "re-detection through the calibration added" in text and "corners" in text
    # A file that is no calibration is refused in words, before any detection.
    assert cli(["detect", *left[:1], "--board", "chessboard:9x6:1mm", "--refine-with", str(out)]) == 2
    assert "format" in capsys.readouterr().err

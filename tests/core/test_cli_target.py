"""freecal detect --target T.json: several boards on one object, from the command line."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from backend.cli import main as cli
from calib_core.synth import render_target, targets


@pytest.mark.slow
def test_detect_with_a_target_writes_one_3d_view_per_image(tmp_path, capsys):
    t = targets.corner()
    t.save(tmp_path / "corner.json")
    rng = np.random.default_rng(5)
    for k, pose in enumerate(targets.corner_poses(3, rng)):
        cv2.imwrite(str(tmp_path / f"view{k}.png"), render_target.render_target("radial", t, pose, rng))
    out = tmp_path / "obs.json"
    images = [str(tmp_path / f"view{k}.png") for k in range(3)]
    assert cli(["detect", *images, "--target", str(tmp_path / "corner.json"), "-q", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "boards (corners)" in text and "wall x" in text and "3/3 images used" in text
    doc = json.loads(out.read_text())
    assert doc["target"] == t.to_json() and "board" not in doc
    assert [v["name"] for v in doc["views"]] == ["view0.png", "view1.png", "view2.png"]
    z = np.concatenate([np.asarray(v["object_points"])[:, 2] for v in doc["views"]])
    assert np.ptp(z) > 100   # corners of the floor and of the walls: a 3-D object


def test_detect_takes_a_board_or_a_target_not_both(tmp_path, capsys):
    targets.corner().save(tmp_path / "t.json")
    (tmp_path / "bad.json").write_text('{"format": "freecal.target/1", "boards": []}')
    img = str(tmp_path / "x.png")
    assert cli(["detect", img, "--board", "chessboard:9x6:25mm", "--target", str(tmp_path / "t.json")]) == 2
    assert "--board SPEC" in capsys.readouterr().err
    assert cli(["detect", img]) == 2
    assert cli(["detect", img, "--target", str(tmp_path / "bad.json")]) == 2
    assert "boards: expected a non-empty list" in capsys.readouterr().err

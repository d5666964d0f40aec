"""Bad input at the command line: exit status 2, one line on stderr that says what to
do, no traceback, and no output file (not even half of one)."""
from __future__ import annotations

import json
import zlib

import cv2
import pytest

from backend.cli import main

from ..conftest import synthetic
from ..service.test_hardening_inputs import board_image, fronto_parallel_views


def write(path, content) -> str:
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content if isinstance(content, str) else json.dumps(content))
    return str(path)


def obs(**changes) -> dict:
    doc = synthetic("radial").train.to_json()
    doc.update(changes)
    return doc


def nan_doc() -> str:
    doc = obs()
    doc["views"][0]["image_points"][0][0] = float("nan")
    return json.dumps(doc)  # Python writes NaN: not JSON, but what a buggy exporter leaves


CASES = {  # name: (files to write {name: content}, argv with {dir}, words in the message)
    "missing file": ({}, ["calibrate", "{dir}/nope.json"], ["no such file"]),
    "not JSON": ({"a.json": "{nope"}, ["calibrate", "{dir}/a.json"], ["not valid JSON", "line 1"]),
    "not UTF-8": ({"a.json": b"\xff\xfe\x00garbage"}, ["calibrate", "{dir}/a.json"], ["UTF-8"]),
    "wrong format": ({"a.json": obs(format="opencv/1")}, ["calibrate", "{dir}/a.json"], ["format"]),
    "NaN in a point": ({"a.json": nan_doc()}, ["calibrate", "{dir}/a.json"], ["not finite"]),
    "duplicate view names": ({"a.json": obs(views=[obs()["views"][0]] * 4)}, ["calibrate", "{dir}/a.json"],
                             ["appears twice"]),
    "too few views": ({"a.json": obs(views=obs()["views"][:2])}, ["calibrate", "{dir}/a.json", "--method", "bspline", "--intervals", "4"],
                      ["at least 3 views"]),
    "negative lambda": ({"a.json": obs()}, ["calibrate", "{dir}/a.json", "--method", "bspline", "--lambda-smooth", "-1"], ["lambda_smooth"]),
    "zero intervals": ({"a.json": obs()}, ["calibrate", "{dir}/a.json", "--method", "bspline", "--intervals", "0"], ["intervals"]),
    "unknown method": ({"a.json": obs()}, ["calibrate", "{dir}/a.json", "--method", "magic"], ["magic"]),
    "bad --set": ({"a.json": obs()}, ["calibrate", "{dir}/a.json", "--set", "novalue"], ["KEY=VALUE"]),
    "detect: no such folder": ({}, ["detect", "{dir}/none", "--board", "chessboard:6x4:20mm"], ["no such file"]),
    "detect: malformed board": ({"a.png": cv2.imencode(".png", board_image(0))[1].tobytes()},
                                ["detect", "{dir}/a.png", "--board", "chessboard:nine"], ["chessboard:9x6"]),
    "detect: board of a million corners": ({"a.png": cv2.imencode(".png", board_image(0))[1].tobytes()},
                                           ["detect", "{dir}/a.png", "--board", "chessboard:1000000x3:25mm"],
                                           ["1000000x3", "at most 100x100"]),
    "detect: ChArUco board of a million squares": ({"a.png": cv2.imencode(".png", board_image(0))[1].tobytes()},
                                                   ["detect", "{dir}/a.png", "--board",
                                                    "charuco:1000x1000:40mm:20mm:DICT_6X6_250"], ["at most 100x100"]),
    "detect: a 23-digit square size": ({"a.png": cv2.imencode(".png", board_image(0))[1].tobytes()},
                                       ["detect", "{dir}/a.png", "--board", "chessboard:9x6:" + "9" * 23 + "mm"],
                                       ["square size", "from 0.001 mm to 10 m"]),
    "detect: no images in the folder": ({"notes.txt": "hi"}, ["detect", "{dir}", "--board", "chessboard:6x4:20mm"],
                                        ["no images"]),
    "JSON nested 100 000 deep": ({"a.json": "[" * 100_000 + "]" * 100_000}, ["calibrate", "{dir}/a.json"],
                                 ["a.json", "more than 32 levels deep"]),
    "JSON nested 40 deep": ({"a.json": obs(board=json.loads('{"a": ' * 40 + "1" + "}" * 40))},
                            ["calibrate", "{dir}/a.json"], ["more than 32 levels deep"]),
    "a 5000-digit number": ({"a.json": json.dumps(obs()).replace('"image_size": [', '"image_size": [' + "9" * 5000, 1)},
                            ["calibrate", "{dir}/a.json"], ["a.json", "number is too long"]),
    "a view named with a lone surrogate": ({"a.json": obs(views=[{**v, "name": v["name"] + "\ud800x"}
                                                                 for v in obs()["views"]])},
                                           ["calibrate", "{dir}/a.json"], ["views[0].name", "not valid Unicode"]),
    "--set of a setting with its own flag": ({"a.json": obs()}, ["calibrate", "{dir}/a.json", "--method", "zhang",
                                                                 "--set", "outlier_sigma=3"], ["--outlier-sigma 3"]),
    "--set and the flag of one setting": ({"a.json": obs()}, ["calibrate", "{dir}/a.json", "--method", "bspline",
                                                              "--intervals", "4", "--set", "intervals=5"],
                                          ["--intervals 5"]),
    "--set of a parameter that is no setting": ({"a.json": obs()}, ["calibrate", "{dir}/a.json", "--set", "progress=1"],
                                                ["not a method setting"]),
    "rig: --set of a setting with its own flag": ({"a.json": obs(), "b.json": obs()},
                                                  ["rig", "{dir}/a.json", "{dir}/b.json", "--set", "outlier_sigma=3"],
                                                  ["--outlier-sigma 3"]),
    "object points x1e100": ({"a.json": obs(views=[{**v, "object_points": [[c * 1e100 for c in p] for p in v["object_points"]]}
                                                   for v in obs()["views"]])},
                             ["calibrate", "{dir}/a.json", "--method", "zhang"], ["object_points", "out of range"]),
    "rig: a camera name YAML would misread": ({"a.json": obs(), "b.json": obs()},
                                              ["rig", "{dir}/a.json", "{dir}/b.json", "--names", "a\nb: evil,c"],
                                              ["--names", "'a\\nb: evil' is not a camera name"]),
    "rig: a file whose name is no camera name": ({"a #1.json": obs(), "b.json": obs()},
                                                 ["rig", "{dir}/a #1.json", "{dir}/b.json"], ["a file's name", "--names"]),
    "evaluate: a calibration that is not one": ({"c.json": {"format": "freecal.calibration/1", "image_size": [1, True]},
                                                 "a.json": obs()}, ["evaluate", "{dir}/c.json", "{dir}/a.json"],
                                                ["image_size"]),
}


@pytest.mark.parametrize("case", list(CASES))
def test_cli_bad_input_is_one_line_and_exit_2(tmp_path, capsys, case):
    files, argv, words = CASES[case]
    for name, content in files.items():
        write(tmp_path / name, content)
    out = tmp_path / "out.json"
    argv = [a.format(dir=tmp_path) for a in argv]
    argv += ["-o", str(out)] if argv[0] in ("calibrate", "detect") else []
    assert main(argv + (["-q"] if argv[0] in ("calibrate", "detect") else [])) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"freecal {argv[0]}: error: ")
    for w in words:
        assert w in err, err
    assert not out.exists() and not list(tmp_path.glob(".*.tmp")), "no output, not even half of one"


def test_cli_refuses_fronto_parallel_views(tmp_path, capsys):
    """Face-on views fit with a low rmse but an arbitrary focal length: refused, saying what to shoot."""
    path = write(tmp_path / "a.json", fronto_parallel_views())
    assert main(["calibrate", path, "-q", "--method", "bspline", "--intervals", "4", "-o", str(tmp_path / "out.json")]) == 2
    err = capsys.readouterr().err
    assert "fronto-parallel" in err and "tilted" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out.json").exists()


@pytest.fixture(scope="module")
def zhang_cal() -> dict:
    from calib_core import calibrate

    return calibrate(synthetic("radial").train, "zhang").to_json()


def edited(cal: dict, **distortion) -> dict:
    return {**cal, "distortion": {**cal["distortion"], **distortion}}


CAL_CASES = {  # name: (the calibration edited, argv after the calibration file, words in the message)
    "NaN in an opencv model's coefficients": (lambda c: edited(c, coefficients=[float("nan")] * 5), ["evaluate"],
                                              ["distortion.coefficients", "finite"]),
    "Inf in a fisheye model's coefficients": (lambda c: edited(c, type="fisheye", coefficients=[0.1, float("inf")]),
                                              ["evaluate"], ["distortion.coefficients", "finite"]),
    "an MLS support of 1e300": (lambda c: edited(c, type="mls", parametric=c["distortion"], samples=[[500.0, 600.0]],
                                                 offsets_x=[0.0], offsets_y=[0.0], sigma=100.0, support=1e300),
                                ["export", "--to", "mrcal"], ["distortion.support", "image diagonals"]),
    "a B-spline control value of 1e300": (lambda c: {**c, "model": "bspline", "distortion": bspline_field(c)},
                                          ["evaluate"], ["distortion.control_x", "not a lens's field"]),
    "a hybrid's control value of 1e300": (lambda c: {**c, "model": "bspline", "distortion": {
        "type": "hybrid", "core": c["distortion"], "field": bspline_field(c)}}, ["export", "--to", "mrcal"],
                                          ["distortion.field.control_x", "not a lens's field"]),
    "undistort: an image_size of 100000 x 100000": (lambda c: {**c, "image_size": [100_000, 100_000]}, ["undistort"],
                                                    ["the calibration's image_size", "100000 × 100000"]),
}


def bspline_field(cal: dict) -> dict:
    """A bicubic field of 4 x 4 control values over the image, one of them 1e300 px."""
    w, h = cal["image_size"]
    control = [[0.0] * 4 for _ in range(4)]
    control[1][2] = 1e300
    return {"type": "bspline", "degree": [3, 3], "knots_u": [0.0] * 4 + [float(w)] * 4,
            "knots_v": [0.0] * 4 + [float(h)] * 4, "control_x": control, "control_y": [[0.0] * 4 for _ in range(4)]}


@pytest.mark.parametrize("case", list(CAL_CASES))
def test_cli_refuses_a_bad_calibration(tmp_path, capsys, zhang_cal, case):
    edit, argv, words = CAL_CASES[case]
    cal = write(tmp_path / "c.json", json.dumps(edit(zhang_cal)))  # json writes NaN and Infinity as a buggy exporter does
    argv = [argv[0], cal, *argv[1:]]
    if argv[0] == "evaluate":
        argv.append(write(tmp_path / "a.json", obs()))
    else:
        argv += ["-o", str(tmp_path / "out")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"freecal {argv[0]}: error: ")
    for w in words:
        assert w in err, err


def test_undistort_refuses_an_image_of_too_many_pixels(tmp_path, capsys, zhang_cal):
    """A PNG whose header declares 40000x40000: refused in detect's words, not with OpenCV's assertion."""
    small = cv2.imencode(".png", board_image(0))[1].tobytes()
    ihdr = small[12:16] + (40000).to_bytes(4, "big") * 2 + small[24:29]  # IHDR: 40000x40000, past any limit
    bomb = small[:12] + ihdr + zlib.crc32(ihdr).to_bytes(4, "big") + small[33:]
    image = write(tmp_path / "bomb.png", bomb)
    out = tmp_path / "out"
    assert main(["undistort", write(tmp_path / "c.json", zhang_cal), image, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert "bomb.png" in err and "more pixels than the limit" in err and not out.exists()


def test_report_refuses_observations_with_a_fitted_view_emptied(tmp_path, capsys, zhang_cal):
    """A view the calibration was fitted to, with no corners in the observations given: said, not a LinAlgError."""
    doc = obs()
    doc["views"][0].update(object_points=[], image_points=[], ids=[])
    out = tmp_path / "r.html"
    assert main(["report", write(tmp_path / "c.json", zhang_cal), write(tmp_path / "a.json", doc), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert "no corners in 1 of the calibration's" in err and repr(doc["views"][0]["name"]) in err and not out.exists()


def test_kalibr_quotes_a_topic_yaml_would_misread(zhang_cal):
    """Whatever a camera's name, the camchain stays YAML that reads back the same topic."""
    import yaml

    from calib_core import Calibration
    from calib_core.exports.kalibr import camera_entry
    from calib_core.exports.targets import export

    fit = export(Calibration.from_json(zhang_cal), "kalibr").fit
    topic = "/a\nb: evil, #c/image_raw"
    assert yaml.safe_load(camera_entry(0, fit, topic))["cam0"]["rostopic"] == topic

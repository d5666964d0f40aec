"""Bad input at the command line: exit status 2, one line on stderr that says what to
do, no traceback, and no output file (not even half of one)."""
from __future__ import annotations

import json

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

"""Standard input and output at the command line: ``-`` reads or writes a document,
``--json`` prints the machine-readable result on stdout and nothing else there (the
text a person reads moves to stderr), so commands chain with pipes; and
``freecal --version``."""
from __future__ import annotations

import importlib.metadata
import io
import json
import os
import subprocess
import sys

import cv2
import pytest

from backend.cli import main

from ..conftest import ROOT, shared_data
from .cli_files import calibration_json, files  # noqa: F401  (the fixture)

ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def freecal(*argv: str, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "backend.cli", *argv], capture_output=True, env=ENV, timeout=300, **kw)


def test_version_is_the_installed_package_version():
    run = freecal("--version")
    assert run.returncode == 0
    assert run.stdout.decode().strip() == f"freecal {importlib.metadata.version('freecal')}"


@pytest.mark.slow
def test_detect_json_pipes_into_calibrate(tmp_path):
    """freecal detect PHOTOS --json | freecal calibrate - --json: each stdout is one
    document; the per-image table and the progress are on stderr."""
    photos = sorted(str(p) for p in shared_data("opencv-stereo-9x6").glob("left0*.jpg"))[:6]
    detect = subprocess.Popen([sys.executable, "-m", "backend.cli", "detect", *photos, "--board", "chessboard:9x6:25mm",
                               "--json", "--workers", "1"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=ENV)
    tee = tmp_path / "obs.json"
    observations = detect.stdout.read()
    tee.write_bytes(observations)
    detect.wait(timeout=120)
    detect_err = detect.stderr.read().decode()
    assert detect.returncode == 0, detect_err
    obs = json.loads(observations)
    assert obs["format"] == "freecal.observations/1" and len(obs["views"]) == 6
    assert "6/6 images used" in detect_err and "detecting: 6/6 images" in detect_err
    cal = freecal("calibrate", "-", "--method", "zhang", "--json", input=observations)
    assert cal.returncode == 0, cal.stderr.decode()
    doc = json.loads(cal.stdout)
    assert doc["format"] == "freecal.calibration/1" and [v["name"] for v in doc["views"]] == [
        v["name"] for v in obs["views"]]
    assert "levenberg-marquardt" in cal.stderr.decode()  # progress, on stderr
    # the same through -o - and a file: identical corners
    again = freecal("detect", *photos, "--board", "chessboard:9x6:25mm", "-o", "-", "-q", "--workers", "1")
    assert json.loads(again.stdout) == obs and "images used" in again.stderr.decode()


@pytest.mark.slow
def test_export_reads_stdin_and_writes_stdout(files):  # noqa: F811
    """freecal export - --to opencv -o - < cal.json: the YAML alone on stdout, read by OpenCV."""
    with open(files["cal"], "rb") as f:
        run = freecal("export", "-", "--to", "opencv", "-o", "-", stdin=f)
    assert run.returncode == 0, run.stderr.decode()
    fs = cv2.FileStorage(run.stdout.decode(), cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    k = fs.getNode("camera_matrix").mat()
    assert k[0, 0] == pytest.approx(calibration_json()["intrinsics"]["fx"], abs=1e-9)
    assert "exact" in run.stderr.decode()  # the note for the person, on stderr


def test_calibrate_dash_output_is_the_file(files, capsys, tmp_path):  # noqa: F811
    assert main(["calibrate", files["obs"], "--method", "zhang", "-q", "-o", "-"]) == 0
    out, err = capsys.readouterr()
    doc = json.loads(out)
    assert doc["format"] == "freecal.calibration/1"
    assert "overall" in err, "the summary for the person goes to stderr when stdout carries the file"
    assert main(["calibrate", files["obs"], "--method", "zhang", "-q", "-o", str(tmp_path / "c.json")]) == 0
    again = json.loads((tmp_path / "c.json").read_text())
    for d in (doc, again):  # what differs between two runs: the time they took and when they ran
        d["diagnostics"]["solver"].pop("seconds")
        d["provenance"].pop("created")
    assert doc == again


@pytest.mark.parametrize("stdin, words", [(b"", "empty"), (b"\xff\xfe", "UTF-8"), (b"{nope", "not valid JSON"),
                                          (None, "nothing is piped in")])
def test_bad_standard_input_is_one_line(monkeypatch, capsys, stdin, words):
    class Terminal(io.TextIOWrapper):
        def isatty(self):
            return True

    fake = (Terminal if stdin is None else io.TextIOWrapper)(io.BytesIO(stdin or b""))
    monkeypatch.setattr(sys, "stdin", fake)
    assert main(["calibrate", "-", "-q"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and words in err and "Traceback" not in err, err
    if stdin is not None:
        assert "standard input" in err


def test_one_document_on_standard_input(files, capsys):  # noqa: F811
    assert main(["evaluate", "-", "-"]) == 2
    assert "only one input can be read from standard input" in capsys.readouterr().err


JSON_RUNS = {  # command: (argv with {obs}, {cal}, {dir}; a key of its JSON)
    "calibrate": (["calibrate", "{obs}", "--method", "zhang", "-q", "--json"], "metrics"),
    "evaluate": (["evaluate", "{cal}", "{obs}", "--json"], "rmse"),
    "compare": (["compare", "{obs}", "--methods", "zhang,fisheye", "--splits", "0", "-q", "--json"], "verdict"),
    "export": (["export", "{cal}", "--to", "opencv8", "-o", "{dir}/cal.yaml", "--json"], "fit_error"),
    "undistort": (["undistort", "{cal}", "-o", "{dir}/maps", "--size", "128x160", "--json"], "rectified_camera"),
    "synth": (["synth", "-o", "{dir}/set", "--json"], "written"),
    "diff": (["diff", "{cal}", "{cal}", "--json"], "rotation_deg"),
    "report": (["report", "{cal}", "-o", "{dir}/report.html", "--json"], "report"),
}


@pytest.mark.parametrize("command", list(JSON_RUNS))
def test_json_is_the_only_thing_on_stdout(files, capsys, command):  # noqa: F811
    argv, key = JSON_RUNS[command]
    assert main([a.format(**files) for a in argv]) == 0
    out, err = capsys.readouterr()
    doc = json.loads(out)  # the whole of stdout is one document
    assert key in doc, doc.keys()
    assert "Traceback" not in err


@pytest.mark.slow
def test_demo_json(capsys):
    assert main(["demo", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [row["lens"] for row in doc["lenses"]] == ["radial", "fisheye", "asymmetric"]
    assert all(row["holdout_rmse"] < 1.0 for row in doc["lenses"])

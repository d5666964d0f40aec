"""Progress as a person sees it: on a terminal a bar with the time left (rich), in a
pipe or a log plain lines, one per stage, each naming the candidate model it
belongs to (the default tries five: five bare "initialise" lines said nothing)."""
from __future__ import annotations

import os
import pty
import re
import subprocess
import sys

import pytest

from ..conftest import ROOT

pytestmark = pytest.mark.slow
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "TERM": "xterm-256color", "COLUMNS": "120"}
CANDIDATES = ("OpenCV 5-coefficient model", "Kannala-Brandt model", "OpenCV rational model",
              "B-spline field over the rational model")


@pytest.fixture(scope="module")
def corners(tmp_path_factory):
    from ..conftest import synthetic

    path = tmp_path_factory.mktemp("progress") / "train.json"
    synthetic("asymmetric").train.save(path)  # a lens that needs a field: every candidate runs
    return str(path)


def calibrate_argv(corners: str, tmp: str) -> list[str]:
    return [sys.executable, "-m", "backend.cli", "calibrate", corners, "-o", f"{tmp}/cal.json"]


def test_plain_lines_name_each_candidate_when_not_a_terminal(corners, tmp_path):
    run = subprocess.run(calibrate_argv(corners, str(tmp_path)), capture_output=True, text=True, env=ENV, timeout=300)
    assert run.returncode == 0, run.stderr
    lines = run.stderr.splitlines()
    assert "\x1b" not in run.stderr, "no terminal codes in a log"
    stages = [re.sub(r"^\[\s*[\d.]+ s\]\s+\d+ %\s+", "", line) for line in lines]
    assert all(re.match(r"^\[\s*[\d.]+ s\]\s+\d+ %\s+\S", line) for line in lines), lines
    for label in CANDIDATES:
        assert f"{label}: initialise" in stages, stages
    assert "initialise" not in stages, "every stage of a candidate says which candidate"
    assert "model choice" in stages and stages[-1] == "done"
    assert all(a != b for a, b in zip(stages, stages[1:], strict=False)), "one line per stage, not one per call"


def test_a_terminal_gets_a_bar_with_the_time_left(corners, tmp_path):
    master, slave = pty.openpty()
    proc = subprocess.Popen(calibrate_argv(corners, str(tmp_path)), stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=slave, env=ENV)
    os.close(slave)
    screen = b""
    while True:
        try:
            chunk = os.read(master, 65536)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        screen += chunk
    assert proc.wait(timeout=300) == 0
    text = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", screen.decode("utf-8", "replace"))
    assert "━" in text, "a drawn bar"
    assert re.search(r"\d+%\s+\d:\d\d:\d\d left \d:\d\d:\d\d", text), text[-500:]  # elapsed, then the time left
    # which stages get drawn depends on the bar's refresh (10 per second) against the stages' length:
    # the candidates' names are asserted on the plain lines above, where every stage prints
    assert not re.search(r"^\[\s*[\d.]+ s\]", text, re.M), "no plain lines on a terminal"

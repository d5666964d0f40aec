"""Files the command-line tests start from: corners, a calibration of their camera, a folder."""
from __future__ import annotations

import functools
import json

import pytest

from calib_core import calibrate

from ..conftest import synthetic


@functools.cache
def calibration_json() -> dict:
    return calibrate(synthetic("radial").train, "zhang").to_json()


@pytest.fixture
def files(tmp_path):
    """An observations file, a calibration of the same camera and an empty folder, by name."""
    obs, cal, folder = tmp_path / "obs.json", tmp_path / "cal.json", tmp_path / "folder"
    synthetic("radial").train.save(obs)
    cal.write_text(json.dumps(calibration_json()))
    folder.mkdir()
    return {"obs": str(obs), "cal": str(cal), "dir": str(folder), "tmp": str(tmp_path)}



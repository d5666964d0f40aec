"""A calibration records where it came from: the freecal version, the date, a
hash of its observations (reproducible from the observations file alone, by
the recipe docs/formats.md's reader needs no freecal for), the units of tvec;
the contract's required fields untouched."""
from __future__ import annotations

import hashlib
import json
from datetime import UTC, datetime, timedelta
from importlib.metadata import version

from calib_core import Calibration, Observations
from calib_core.pipeline import calibrate
from calib_core.report.tables import report_files

from ..conftest import synthetic


def test_a_calibration_records_version_date_observations_hash_and_tvec_units(tmp_path):
    obs = synthetic("radial").train
    obs.save(tmp_path / "obs.json")
    before = datetime.now(UTC).replace(microsecond=0)
    cal = calibrate(Observations.load(tmp_path / "obs.json"), "zhang")
    p = cal.to_json()["provenance"]
    assert p["freecal_version"] == version("freecal")
    created = datetime.fromisoformat(p["created"].replace("Z", "+00:00"))
    assert p["created"].endswith("Z") and before <= created <= datetime.now(UTC) + timedelta(seconds=1)
    assert p["tvec_units"] == obs.board["units"] == "mm"
    # the hash, from the file: freecal's canonical form of the corners, keys sorted, no spaces
    canonical = Observations.from_json(json.loads((tmp_path / "obs.json").read_text())).to_json()
    text = json.dumps(canonical, sort_keys=True, separators=(",", ":"))
    assert p["observations_sha256"] == hashlib.sha256(text.encode()).hexdigest()
    other = synthetic("radial", seed=1).train
    assert calibrate(other, "zhang").provenance["observations_sha256"] != p["observations_sha256"]


def test_provenance_survives_a_round_trip_and_leaves_the_contract_alone(tmp_path):
    cal = calibrate(synthetic("radial").train, "zhang")
    cal.save(tmp_path / "cal.json")
    doc = json.loads((tmp_path / "cal.json").read_text())
    plain = dict(doc)
    del plain["provenance"]
    back = Calibration.from_json(plain)  # a reader without it (or a file from before) loses nothing else
    assert back.provenance == {} and back.to_json() == plain
    assert Calibration.load(tmp_path / "cal.json").provenance == cal.provenance
    doc["provenance"] = "not ours"  # an extra field of someone else's: ignored, as formats.md says
    assert Calibration.from_json(doc).provenance == {}


def test_the_service_files_carry_it_too():
    obs = synthetic("radial").train
    cal = calibrate(obs, "zhang")
    assert report_files(cal, obs)["calibration.json"]["provenance"] == cal.provenance

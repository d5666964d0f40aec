"""Rig jobs over real HTTP (`freecal serve` with its worker): several ready sets, one per
camera, calibrated together by the worker; rig.json is what `freecal rig` writes for the
same corners, the exports read back with OpenCV's and PyYAML's readers, bad requests
refused up front in words, and a running rig cancelled."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from backend.cli import main
from calib_core.rig import Rig

from ..core.test_rig import TRUE_EXTRINSICS, simulated_rig
from .harness import FAST, SLOW, Service, wait_job


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    root = tmp_path_factory.mktemp("rigs")
    svc = Service(root / "data", root, {**FAST, "FREECAL_MAX_RIG_CAMERAS": "3", "FREECAL_VIEWER": "0"}).start()
    yield svc
    svc.stop()


def upload(service, path_or_doc, filename: str) -> str:
    text = path_or_doc.read_text() if hasattr(path_or_doc, "read_text") else json.dumps(path_or_doc)
    r = service.client.post("/api/sets", files={"files": (filename, text, "application/json")})
    assert r.status_code == 201, r.text
    return r.json()["id"]


@pytest.fixture(scope="module")
def pair_sets(service, stereo_pair_files):
    return [upload(service, path, path.name) for path in stereo_pair_files]


def without_timings(doc):
    """The document less its wall-clock fields (the solvers' ``seconds``, provenance's ``created``)."""
    if isinstance(doc, dict):
        return {k: without_timings(v) for k, v in doc.items() if k not in ("seconds", "created")}
    if isinstance(doc, list):
        return [without_timings(v) for v in doc]
    return doc


@pytest.mark.slow  # the rig, then Kalibr's export fits a model per camera: about 10 s
def test_a_rig_job_writes_what_freecal_rig_writes_and_its_exports_read_back(service, stereo_pair_files, pair_sets, tmp_path):
    c = service.client
    r = c.post("/api/jobs", json={"kind": "rig", "set_ids": pair_sets, "method": "zhang"})
    assert r.status_code == 201, r.text
    created = r.json()
    assert created["kind"] == "rig" and created["set_id"] is None and created["state"] == "queued"
    assert created["rig"] == {"set_ids": pair_sets, "names": ["left", "right"], "reference": "left",
                              "hold_models": False}
    seen: list[dict] = []
    job = wait_job(c, created["id"], 120, service.logs(), seen=seen)
    assert job["state"] == "done", job["error"]
    assert any(j["state"] == "running" and j["stage"].startswith("camera left") for j in seen)
    assert set(job["downloads"]) == {"rig.json", "camchain.yaml", "stereo.yaml"}

    # the summary, in the job and in the list of rig jobs (calibrations alone are the default list)
    summary = job["summary"]
    assert [cam["name"] for cam in summary["cameras"]] == ["left", "right"]
    assert all(0.1 < cam["rmse"] < 0.4 and cam["n_frames"] == 8 and cam["model"] == "zhang"
               for cam in summary["cameras"])
    assert summary["n_frames"] == 8 and 0.1 < summary["metrics"]["rmse"] < 0.4 and summary["models_refined"]
    # the right camera's place: the simulated rig's (tests/core/test_rig.py: TRUE_EXTRINSICS), from rig.json's pose
    right = summary["cameras"][1]
    true = TRUE_EXTRINSICS[1]
    centre = -Rotation.from_rotvec(true[:3]).inv().apply(true[3:])
    assert np.allclose(right["centre"], centre, atol=3.0) and abs(right["distance"] - np.linalg.norm(centre)) < 3.0
    assert abs(right["rotation_deg"] - np.degrees(np.linalg.norm(true[:3]))) < 0.5
    assert summary["cameras"][0]["distance"] == 0.0
    listed = c.get("/api/jobs", params={"kind": "rig"}).json()["jobs"]
    assert [j["id"] for j in listed] == [job["id"]] and listed[0]["summary"] == summary
    assert job["id"] not in [j["id"] for j in c.get("/api/jobs").json()["jobs"]]

    # rig.json: freecal.rig/1, what `freecal rig` writes for the same corners (but for the solver's seconds)
    r = c.get(job["downloads"]["rig.json"])
    assert r.status_code == 200 and r.headers["content-type"].startswith("application/json")
    assert f'filename="freecal-job-{job["id"]}-rig.json"' in r.headers["content-disposition"]
    cli_rig = tmp_path / "rig.json"
    assert main(["rig", *map(str, stereo_pair_files), "--method", "zhang", "-o", str(cli_rig), "-q"]) == 0
    assert without_timings(r.json()) == without_timings(json.loads(cli_rig.read_text()))
    rig = Rig.from_json(r.json())

    # OpenCV's stereo file: cv2.FileStorage reads it; the same text as `freecal export rig.json --to opencv`
    r = c.get(job["downloads"]["stereo.yaml"])
    assert r.status_code == 200 and r.headers["content-type"].startswith("application/x-yaml")
    assert f'filename="freecal-job-{job["id"]}-stereo.yaml"' in r.headers["content-disposition"]
    stereo = tmp_path / "stereo.yaml"
    stereo.write_bytes(r.content)
    fs = cv2.FileStorage(str(stereo), cv2.FILE_STORAGE_READ)
    m = {key: fs.getNode(key).mat() for key in ("M1", "D1", "M2", "D2", "R", "T")}
    assert fs.getNode("camera_2").string() == "right"
    right = rig.camera("right")
    assert np.allclose(cv2.Rodrigues(m["R"])[0].ravel(), right.rvec, atol=1e-9)
    assert np.allclose(m["T"].ravel(), right.tvec, atol=1e-9)
    downloaded = tmp_path / "downloaded.json"
    downloaded.write_bytes(c.get(job["downloads"]["rig.json"]).content)
    assert main(["export", str(downloaded), "--to", "opencv", "-o", str(tmp_path / "cli_stereo.yaml")]) == 0
    assert (tmp_path / "cli_stereo.yaml").read_bytes() == r.content

    # Kalibr's camchain: PyYAML reads it; cam1 placed from cam0 as the rig places it
    r = c.get(job["downloads"]["camchain.yaml"])
    assert r.status_code == 200 and r.headers["content-type"].startswith("application/x-yaml")
    assert f'filename="freecal-job-{job["id"]}-camchain.yaml"' in r.headers["content-disposition"]
    chain = yaml.safe_load(r.text)
    assert set(chain) == {"cam0", "cam1"} and chain["cam1"]["rostopic"] == "/right/image_raw"
    assert chain["cam0"]["cam_overlaps"] == [1] and chain["cam0"]["resolution"] == [1280, 960]
    t = np.array(chain["cam1"]["T_cn_cnm1"])
    assert np.allclose(t[:3, 3], 1e-3 * right.tvec, atol=1e-9) and np.allclose(t[3], [0, 0, 0, 1])  # mm → Kalibr's metres
    assert np.allclose(cv2.Rodrigues(t[:3, :3])[0].ravel(), right.rvec, atol=1e-6)

    # a rig job's other files do not exist, and saying so names what does
    r = c.get(f"/api/jobs/{job['id']}/calibration.json")
    assert r.status_code == 404 and "rig.json" in r.json()["detail"]


def test_rig_requests_are_refused_up_front_saying_what_to_do(service, stereo_pair_files, pair_sets):
    c = service.client
    left, right = pair_sets
    apart = upload(service, simulated_rig([range(0, 8), range(8, 16)], seed=3)["cam1"].to_json(), "far.json")
    twice = simulated_rig([range(0, 8)], seed=3)["cam0"].to_json()
    twice["views"][1]["frame"] = "000"  # two views of one camera at one frame
    double = upload(service, twice, "double.json")
    other_board = simulated_rig([range(0, 8), range(0, 8)], seed=3)["cam1"].to_json()
    other_board["board"]["square_size"] = 50.0
    other = upload(service, other_board, "other.json")
    png = cv2.imencode(".png", np.full((64, 64), 255, np.uint8))[1].tobytes()  # no board: detection fails
    r = c.post("/api/sets", files={"files": ("blank.png", png, "image/png")}, data={"board": "chessboard:9x6:25mm"})
    assert r.status_code == 201, r.text
    unready = r.json()["id"]
    rig = {"kind": "rig", "method": "zhang"}
    before = c.get("/api/jobs", params={"kind": "rig"}).json()["count"]
    cases = [
        ({"set_ids": [left]}, "two or more cameras"),
        ({"set_ids": [left, right, left, right]}, "over this server's limit of 3 (FREECAL_MAX_RIG_CAMERAS)"),
        ({"set_ids": [left, left]}, "given more than once"),
        ({"set_ids": [left, "nope"]}, "no set with id 'nope'"),
        ({"set_ids": [left, unready]}, "not ready"),
        ({"set_ids": [left, right], "names": ["a", "a"]}, "'a' is given to more than one camera"),
        ({"set_ids": [left, right], "names": ["a"]}, "give one name per set"),
        ({"set_ids": [left, right], "names": ["a", "b/c"]}, "not a camera name"),
        ({"set_ids": [left, right], "reference": "middle"}, "'middle' is not one of the cameras ['left', 'right']"),
        ({"set_ids": [left, apart]}, "share no frame with the reference camera 'left'"),
        ({"set_ids": [left, double]}, "are both frame '000'"),
        ({"set_ids": [left, other]}, "saw another board than camera 'left': square_size 50.0 against 60.0"),
        ({"set_ids": [left, right], "method": "compare"}, "not for a rig"),
        ({"set_ids": [left, right], "method": "magic"}, "unknown method"),
        ({"set_ids": [left, right], "settings": {"no_such": 1}}, "unknown setting"),
        ({"set_ids": "left"}, "set_ids"),
    ]
    for body, words in cases:
        r = c.post("/api/jobs", json={**rig, **body})
        assert r.status_code == 422, (body, r.text)
        assert words in r.json()["detail"], (body, r.json()["detail"])
    apart_detail = c.post("/api/jobs", json={**rig, "set_ids": [left, apart]}).json()["detail"]
    assert "last run of digits in its name" in apart_detail and "\"frame\"" in apart_detail
    assert c.post("/api/jobs", json={"kind": "stereo", "set_ids": [left, right]}).status_code == 422
    assert c.get("/api/jobs", params={"kind": "rig"}).json()["count"] == before  # nothing was created


def test_a_running_rig_job_is_cancelled(service, pair_sets):
    c = service.client
    r = c.post("/api/jobs", json={"kind": "rig", "set_ids": pair_sets, "names": ["a", "b"], "reference": "b",
                                  "method": "bspline", "settings": {**SLOW, "max_iterations": 500},
                                  "hold_models": True})
    assert r.status_code == 201, r.text
    job_id = r.json()["id"]
    assert r.json()["rig"]["reference"] == "b" and r.json()["rig"]["hold_models"]
    wait_job(c, job_id, 60, service.logs(), states=("running",))
    assert c.post(f"/api/jobs/{job_id}/cancel").json()["cancel_requested"]
    job = wait_job(c, job_id, 60, service.logs())
    assert job["state"] == "cancelled" and job["downloads"] == {}
    assert c.get(f"/api/jobs/{job_id}/rig.json").status_code == 409
    assert c.delete(f"/api/jobs/{job_id}").status_code == 204

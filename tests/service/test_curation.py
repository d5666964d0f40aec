"""Curation, board sizes and forgiving uploads over real HTTP (`freecal serve` in a subprocess):

- a job created while its set is still detecting waits in the queue and runs when the corners
  are there (and fails, saying why, when the detection fails);
- views left out of a job (``exclude``), checked against the set, and the per-view flags;
- a board given with the wrong size (squares counted, another board's size) on GoPro's photos
  and on rendered ones: the photos' size is suggested, and detecting again with it works;
- a drop with files that cannot be used keeps the others and lists them with why; mrcal's
  corners.vnl is read as a corners set.
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from calib_core import Calibration, Observations

from ..conftest import shared_data
from ..rendered_boards import whole_board_photos
from .harness import FAST, Service, wait_for, wait_job

pytestmark = pytest.mark.slow
QUICK_ZHANG = {"method": "zhang", "settings": {}}


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    root = tmp_path_factory.mktemp("curation")
    svc = Service(root / "data", root, {**FAST, "FREECAL_VIEWER": "0"}).start()
    yield svc
    svc.stop()


@pytest.fixture(scope="module")
def rendered(tmp_path_factory) -> list[Path]:
    return whole_board_photos(tmp_path_factory.mktemp("rendered"), n=8)


def upload(svc: Service, paths: list[Path], board: str, extra: list[tuple[str, bytes]] = ()) -> dict:
    files = [("files", (p.name, p.read_bytes())) for p in paths] + [("files", e) for e in extra]
    r = svc.client.post("/api/sets", files=files, data={"board": board})
    assert r.status_code == 201, r.text
    return r.json()


def wait_set(svc: Service, set_id: str, timeout: float = 240) -> dict:
    def ended():
        s = svc.client.get(f"/api/sets/{set_id}").json()
        return s if s["state"] in ("ready", "failed", "cancelled") else None

    return wait_for(ended, timeout, f"set {set_id}'s detection to end", svc.logs(), every=0.2)


def job_of(svc: Service, set_id: str, **body) -> dict:
    r = svc.client.post("/api/jobs", json={"set_id": set_id, **QUICK_ZHANG, **body})
    assert r.status_code == 201, r.text
    return r.json()


def test_a_job_waits_for_its_sets_detection_then_views_are_left_out_and_flagged(service, rendered):
    s = upload(service, rendered, "chessboard:9x6:50mm")
    job = job_of(service, s["id"])      # at once: the set is still queued or detecting
    assert job["state"] == "queued" and job["stage"] == "waiting for detection"
    done = wait_job(service.client, job["id"], 240, service.logs())
    assert done["state"] == "done", done["error"]
    assert service.client.get(f"/api/sets/{s['id']}").json()["state"] == "ready"
    views = service.client.get(f"/api/jobs/{job['id']}/view_residuals.json").json()
    assert len(views) == 8
    for v in views:   # the curation figures of every view: corners kept of found, flags in words
        assert v["n_kept"] <= v["n_detected"] == 54 and isinstance(v["flags"], list)
    assert not [v for v in views if v["flags"]], views   # a clean rendered set: nothing suspicious

    out = [rendered[1].name, rendered[5].name]
    rerun = job_of(service, s["id"], method="rational", exclude=out)
    assert rerun["exclude"] == out and "exclude_views" not in rerun["settings"]
    done = wait_job(service.client, rerun["id"], 240, service.logs())
    assert done["state"] == "done", done["error"]
    assert done["summary"]["n_views"] == 6 and done["summary"]["excluded_views"] == 2
    cal = service.client.get(f"/api/jobs/{rerun['id']}/calibration.json").json()
    assert sorted(v["name"] for v in cal["views"]) == sorted(p.name for p in rendered if p.name not in out)
    assert cal["diagnostics"]["excluded_views"] == out
    listed = service.client.get("/api/jobs", params={"set_id": s["id"]}).json()["jobs"]
    assert {j["id"] for j in listed} == {job["id"], rerun["id"]}   # the set's calibrations, side by side

    for exclude, words in ((["nope.png"], "'nope.png' is not in this set"),
                           ([rendered[0].name, rendered[0].name], "more than once"),
                           ([p.name for p in rendered[:6]], "needs at least 3"),
                           (["x" * 300], "no view of this set")):
        r = service.client.post("/api/jobs", json={"set_id": s["id"], "exclude": exclude})
        assert r.status_code == 422 and words in r.json()["detail"], r.text


def test_gopro_board_given_by_its_squares_is_corrected(service):
    photos = sorted(shared_data("gopro-hero3-wide-15x9").glob("*.JPG"))[:6]
    s = wait_set(service, upload(service, photos, "chessboard:16x10:26mm")["id"], 300)
    assert s["state"] == "ready"   # the corners are found, but not the board's whole 16 x 10
    hint = s["board_suggestion"]
    assert (hint["cols"], hint["rows"], hint["n_photos"], hint["n_images"]) == (15, 9, 6, 6)
    assert hint["spec"] == "chessboard:15x9:26mm"
    assert "15 × 9 inner corners" in hint["message"] and "--board" not in hint["message"]
    assert any("15 × 9" in w for w in s["warnings"])


def test_gopro_board_given_another_size_fails_saying_so_and_detects_again(service):
    photos = sorted(shared_data("gopro-hero3-wide-15x9").glob("*.JPG"))[:6]
    s = upload(service, photos, "chessboard:9x6:26mm")
    waiting = job_of(service, s["id"])
    s = wait_set(service, s["id"])
    assert s["state"] == "failed"
    assert "found in none of the 6 photos" in s["error"] and "--board" not in s["error"]   # the upload's count
    assert "15 × 9 inner corners" in s["error"]
    assert all("--board" not in im["reason"] for im in s["images"])
    failed = wait_job(service.client, waiting["id"], 60, service.logs())
    assert failed["state"] == "failed" and "corner detection failed" in failed["error"]
    assert s["board_suggestion"]["spec"] == "chessboard:15x9:26mm"

    r = service.client.post(f"/api/sets/{s['id']}/detect", json={"board": s["board_suggestion"]["spec"]})
    assert r.status_code == 202, r.text
    assert r.json()["board"]["cols"] == 15 and r.json()["state"] in ("queued", "detecting")
    again = job_of(service, s["id"])    # waits for the new corners
    s = wait_set(service, s["id"])
    assert s["state"] == "ready" and s["n_views"] == 6 and s.get("board_suggestion") is None
    done = wait_job(service.client, again["id"], 240, service.logs())
    assert done["state"] == "done", done["error"]
    busy = service.client.post(f"/api/sets/{s['id']}/detect", json={"board": "charuco:5x7"})
    assert busy.status_code == 422   # a bad spec says so, before anything is queued


def test_rendered_board_given_by_its_squares_is_corrected(service, rendered):
    s = wait_set(service, upload(service, rendered[:2], "chessboard:10x7:50mm")["id"], 300)
    assert s["state"] == "ready"
    assert (s["board_suggestion"]["cols"], s["board_suggestion"]["rows"], s["board_suggestion"]["n_photos"]) == (9, 6, 2)


def test_a_drop_keeps_the_usable_files_and_lists_the_others(service, rendered, tmp_path):
    orpc = shared_data("babelcalib-ov-plane-fisheye") / "train"
    reference = next(iter(sorted(orpc.glob("*.orpc"))))
    extra = [(reference.name, reference.read_bytes()), ("broken.jpg", b"\xff\xd8\xff not really a jpeg"),
             ("empty.png", b""), ("notes.txt", b"taken on Monday")]
    s = upload(service, rendered[:4], "chessboard:9x6:50mm", extra)
    assert [im["name"] for im in s["images"]] == [p.name for p in rendered[:4]]
    reasons = {k["name"]: k["reason"] for k in s["skipped"]}
    assert set(reasons) == {reference.name, "broken.jpg", "empty.png", "notes.txt"}
    assert ".orpc files are not read" in reasons[reference.name]
    assert reasons["empty.png"].startswith("empty (0 bytes)") and "does not give its size" in reasons["broken.jpg"]
    assert wait_set(service, s["id"])["state"] == "ready"
    # nothing usable at all: refused, each file with its reason
    r = service.client.post("/api/sets", data={"board": "chessboard:9x6:50mm"},
                            files=[("files", e) for e in extra])
    assert r.status_code == 422 and "none of the files can be used" in r.json()["detail"]
    assert reference.name in r.json()["detail"]


def vnl_of(obs: Observations, cols: int, rows: int, missing: str = "") -> str:
    """mrcal's corners.vnl of the observations: every board corner of each view, '-' where not seen."""
    lines = ["# filename x y level"]
    for v in obs.views:
        seen = dict(zip(v.ids.tolist(), v.image_points.tolist(), strict=True))
        for i in range(cols * rows):
            x, y = seen.get(i, ("-", "-"))
            lines.append(f"{v.name} {x} {y} {'0' if i in seen else '-'}")
    lines.append(f"{missing} - -" if missing else "")
    return "\n".join(lines) + "\n"


def test_mrcal_corners_vnl_is_a_corners_set(service, rendered):
    s = wait_set(service, upload(service, rendered, "chessboard:9x6:50mm")["id"])
    obs = Observations.from_json(service.client.get(f"/api/sets/{s['id']}/observations.json").json())
    text = vnl_of(obs, 9, 6, missing="no_board.png")
    vnl = ("corners.vnl", text.encode())
    r = service.client.post("/api/sets", data={"board": "chessboard:9x6:50mm"},
                            files=[("files", vnl), ("files", (rendered[0].name, rendered[0].read_bytes()))])
    assert r.status_code == 201, r.text
    got = r.json()
    assert got["source"] == "observations" and got["state"] == "ready" and got["n_views"] == len(obs.views)
    assert got["image_size"] == list(obs.image_size)   # from the photo dropped with it
    assert {k["name"] for k in got["skipped"]} == {rendered[0].name, "no_board.png"}
    sent = Observations.from_json(service.client.get(f"/api/sets/{got['id']}/observations.json").json())
    assert [len(v) for v in sent.views] == [len(v) for v in obs.views]
    done = wait_job(service.client, job_of(service, got["id"])["id"], 120, service.logs())
    assert done["state"] == "done", done["error"]
    assert Calibration.from_json(service.client.get(f"/api/jobs/{done['id']}/calibration.json").json()).views

    alone = service.client.post("/api/sets", data={"board": "chessboard:9x6:50mm"}, files=[("files", vnl)])
    assert alone.status_code == 422 and "drop one of them" in alone.json()["detail"]
    wrong = service.client.post("/api/sets", data={"board": "chessboard:10x7:50mm"},
                                files=[("files", vnl), ("files", (rendered[0].name, rendered[0].read_bytes()))])
    assert wrong.status_code == 422 and "a 10 × 7 board has 70" in wrong.json()["detail"], wrong.text
    garbled = service.client.post("/api/sets", data={"board": "chessboard:9x6:50mm"},
                                  files=[("files", ("corners.vnl", b"a.png 1 2 3 4 5\nb.png x\n")),
                                         ("files", (rendered[0].name, rendered[0].read_bytes()))])
    assert garbled.status_code == 422 and "mrcal's corners file" in garbled.json()["detail"]
    assert json.loads(garbled.text)["detail"] and "Traceback" not in garbled.text

"""The service over real HTTP: `freecal serve` (uvicorn + a worker process on the
SQLite queue) in a subprocess, a real SQLite file, real result files."""
from __future__ import annotations

import io
import zipfile

import pytest

from calib_core import Calibration

from ..conftest import shared_data, synthetic
from .harness import FAST, QUICK, SLOW, Service, create_job, start_worker, upload_observations, wait_for, wait_job

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    root = tmp_path_factory.mktemp("service")
    env = {**FAST, "FREECAL_MAX_UPLOAD_BYTES": str(4 * 1024 * 1024), "FREECAL_MAX_FILES": "20"}
    svc = Service(root / "data", root, env).start()
    yield svc
    svc.stop()


def test_job_progress_results_and_restart(service):
    set_id = upload_observations(service.client, synthetic("radial").train.to_json())
    job_id = create_job(service.client, set_id, "auto")  # the default: a model choice, seconds long
    seen: list[dict] = []
    job = wait_job(service.client, job_id, 120, service.logs(), seen=seen)
    assert job["state"] == "done", job["error"]
    running = [j for j in seen if j["state"] == "running"]
    assert running, "never saw the job running"
    stages = {j["stage"].rsplit(": ", 1)[-1] for j in running}  # "<candidate model>: <stage>"
    assert stages & {"initialise", "levenberg-marquardt", "whether a field pays", "knots", "joint optimisation"}
    assert any(0 < j["progress"] < 100 for j in running)
    assert job["progress"] == 100 and job["timings"]["run_seconds"] > 0 and job["timings"]["stages"]

    r = service.client.get(f"/api/jobs/{job_id}/calibration.json")
    assert r.status_code == 200 and r.headers["content-type"].startswith("application/json")
    assert f'filename="freecal-job-{job_id}-calibration.json"' in r.headers["content-disposition"]
    cal = Calibration.from_json(r.json())
    assert cal.method == "auto" and cal.metrics.rmse < 2.0
    csv = service.client.get(f"/api/jobs/{job_id}/corner_residuals.csv")
    assert csv.headers["content-type"].startswith("text/csv")
    assert csv.text.splitlines()[0].startswith("view,index,id,x,y,dx,dy,error,outlier")
    for name in ("view_residuals.json", "heatmap.json", "distortion_field.json", "comparison.csv"):
        assert service.client.get(f"/api/jobs/{job_id}/{name}").status_code == 200, name
    assert service.client.get(f"/api/jobs/{job_id}/knots.json").status_code == 404  # no field, no knots
    # OpenCV's own lens: the default chose OpenCV's model, which OpenCV reads as it is
    assert cal.model.kind == "opencv" and cal.settings["chosen"] == "zhang"
    yaml = service.client.get(f"/api/jobs/{job_id}/opencv.yaml")
    assert yaml.status_code == 200 and "distortion_coefficients" in yaml.text

    before = r.content
    service.restart()
    assert service.client.get(f"/api/sets/{set_id}").json()["state"] == "ready"
    again = service.client.get(f"/api/jobs/{job_id}")
    assert again.json()["state"] == "done"
    assert service.client.get(f"/api/jobs/{job_id}/calibration.json").content == before


def test_cancel_running_job_and_delete(service):
    set_id = upload_observations(service.client, synthetic("radial").train.to_json())
    job_id = create_job(service.client, set_id, settings={**SLOW, "max_iterations": 500})
    wait_job(service.client, job_id, 60, service.logs(), states=("running",))
    r = service.client.post(f"/api/jobs/{job_id}/cancel")
    assert r.status_code == 200 and r.json()["cancel_requested"]
    job = wait_job(service.client, job_id, 60, service.logs())
    assert job["state"] == "cancelled"
    assert service.client.get(f"/api/jobs/{job_id}/calibration.json").status_code == 409
    assert service.client.delete(f"/api/jobs/{job_id}").status_code == 204
    assert service.client.get(f"/api/jobs/{job_id}").status_code == 404
    assert service.client.delete(f"/api/sets/{set_id}").status_code == 204
    assert service.client.get(f"/api/sets/{set_id}").status_code == 404


def test_inline_observations_and_a_parametric_method(service):
    if "zhang" not in service.client.get("/api/methods").json()["methods"]:
        pytest.skip("the zhang method is not in this build yet")
    obs = synthetic("radial").train.to_json()
    r = service.client.post("/api/jobs", json={"observations": obs, "method": "zhang"})
    assert r.status_code == 201, r.text
    job = wait_job(service.client, r.json()["id"], 60, service.logs())
    assert job["state"] == "done", job["error"]
    yaml = service.client.get(job["downloads"]["opencv.yaml"])
    assert yaml.status_code == 200 and "camera_matrix: !!opencv-matrix" in yaml.text


@pytest.mark.parametrize("request_kwargs, status, words", [
    ({"files": {"files": ("notes.txt", b"hello")}, "data": {"board": "chessboard:9x6:25mm"}}, 415, "not an image"),
    ({"files": {"files": ("a.png", b"x")}, "data": {"board": "chessboard:nine"}}, 422, "chessboard:9x6"),
    ({"files": {"files": ("a.png", b"x")}}, 422, "board spec"),
    ({"files": {"files": ("obs.json", b"{not json")}}, 422, "not valid JSON"),
    ({"files": {"files": ("obs.json", b'{"format": "other/1"}')}}, 422, "format"),
    ({"files": {"files": ("set.zip", b"PK not really")}, "data": {"board": "chessboard:9x6:25mm"}}, 422, "zip"),
    ({"files": {"files": ("big.png", b"0" * (5 * 1024 * 1024))}, "data": {"board": "chessboard:9x6:25mm"}},
     413, "limit"),
    ({"files": [("files", (f"{i}.png", b"x")) for i in range(21)], "data": {"board": "chessboard:9x6:25mm"}},
     413, "limit"),
    ({"data": {"board": "chessboard:9x6:25mm"}}, 422, "files"),
])
def test_upload_errors_answer_4xx_with_advice(service, request_kwargs, status, words):
    r = service.client.post("/api/sets", **request_kwargs)
    assert r.status_code == status, r.text
    assert words in r.json()["detail"]


def test_job_errors_answer_4xx_with_advice(service):
    c = service.client
    set_id = upload_observations(c, synthetic("radial").train.to_json())
    cases = [
        ({"set_id": "nope"}, 404, "no set"),
        ({"set_id": set_id, "method": "magic"}, 422, "unknown method"),
        ({"set_id": set_id, "settings": {"lambda_reg": -1}}, 422, "lambda_reg"),
        ({"set_id": set_id, "settings": {"no_such": 1}}, 422, "unknown setting"),
        ({}, 422, "set_id"),
        ({"observations": {"format": "x"}}, 422, "format"),
    ]
    for body, status, words in cases:
        r = c.post("/api/jobs", json=body)
        assert r.status_code == status and words in r.json()["detail"], (body, r.text)
    r = c.post("/api/jobs", content=b"{", headers={"content-type": "application/json"})
    assert r.status_code == 422 and "invalid request" in r.json()["detail"]
    job_id = create_job(c, set_id, settings=QUICK)
    job = wait_job(c, job_id, 60, service.logs())
    assert c.get(f"/api/jobs/{job_id}/nothing.bin").status_code == 404
    assert c.get("/api/jobs/unknown").status_code == 404
    assert c.delete("/api/sets/unknown").status_code == 404
    assert job["state"] == "done"


def test_failed_job_reports_why_in_plain_words(service):
    obs = synthetic("radial").train.to_json()
    obs["views"] = obs["views"][:2]
    r = service.client.post("/api/jobs", json={"observations": obs, "method": "bspline", "settings": QUICK})
    job = wait_job(service.client, r.json()["id"], 60, service.logs())
    assert job["state"] == "failed" and "at least 3 views" in job["error"]


def test_image_set_detection_and_calibration(service):
    pytest.importorskip("calib_core.detection.detect", reason="corner detection (calib_core.detection.detect) is not in this build yet")
    folder = shared_data("opencv-stereo-9x6")
    images = sorted(folder.glob("left*.jpg"))[:8]
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for p in images:
            zf.write(p, f"left/{p.name}")
    r = service.client.post("/api/sets", files={"files": ("left.zip", buf.getvalue(), "application/zip")},
                            data={"board": "chessboard:9x6:25mm"})
    assert r.status_code == 201, r.text
    set_id = r.json()["id"]
    assert [im["name"] for im in r.json()["images"]] == [p.name for p in images]
    seen: list[dict] = []

    def ready():
        s = service.client.get(f"/api/sets/{set_id}").json()
        seen.append(s)
        return s if s["state"] in ("ready", "failed") else None

    s = wait_for(ready, 120, "detection of the image set", service.logs())
    assert s["state"] == "ready", s["error"]
    used = [im for im in s["images"] if im["status"] == "used"]
    assert len(used) >= 6 and all(0 < im["n_corners"] <= 54 for im in used), s["images"]
    assert all(im["reason"] for im in s["images"] if im["status"] == "rejected")
    assert s["n_views"] == len(used) and s["image_size"] == [640, 480] and s["coverage"]["fraction_covered"] > 0
    obs = service.client.get(f"/api/sets/{set_id}/observations.json").json()
    assert obs["format"] == "freecal.observations/1" and len(obs["views"]) == len(used)

    job = wait_job(service.client, create_job(service.client, set_id, "bspline", QUICK), 60, service.logs())
    assert job["state"] == "done", job["error"]
    cal = Calibration.from_json(service.client.get(f"/api/jobs/{job['id']}/calibration.json").json())
    assert cal.metrics.rmse < 1.0


def test_worker_killed_mid_job_is_retried(tmp_path):
    """A worker that dies (SIGKILL) leaves its job to the lease: re-queued, then done by another worker."""
    env = {**FAST}
    svc = Service(tmp_path / "data", tmp_path, env, workers=0).start()
    workers = [start_worker(svc.data_dir, tmp_path, env, "worker-1")]
    try:
        set_id = upload_observations(svc.client, synthetic("radial").train.to_json())
        job_id = create_job(svc.client, set_id, settings=SLOW)
        logs = svc.logs() + workers
        wait_job(svc.client, job_id, 60, logs, states=("running",))
        workers[0].kill()
        workers.append(start_worker(svc.data_dir, tmp_path, env, "worker-2"))
        job = wait_job(svc.client, job_id, 120, svc.logs() + workers)
        assert job["state"] == "done", job["error"]
        assert job["attempts"] == 2
    finally:
        for w in workers:
            w.stop()
        svc.stop()


def test_server_killed_mid_job_then_restarted(tmp_path):
    """`freecal serve` killed outright while its worker runs a job: after a restart the job
    is retried (or failed with the reason), never left running."""
    env = {**FAST, "FREECAL_MAX_ATTEMPTS": "1"}
    svc = Service(tmp_path / "data", tmp_path, env).start()
    try:
        set_id = upload_observations(svc.client, synthetic("radial").train.to_json())
        job_id = create_job(svc.client, set_id, settings=SLOW)
        wait_job(svc.client, job_id, 60, svc.logs(), states=("running",))
        svc.proc.kill()
        svc.start()
        job = wait_job(svc.client, job_id, 60, svc.logs(), states=("failed", "done"))
        assert job["state"] == "failed"
        assert "stopped sending heartbeats" in job["error"] and "1 attempt" in job["error"]
        assert svc.client.get(f"/api/sets/{set_id}").json()["state"] == "ready"
    finally:
        svc.stop()


def test_health_and_methods(service):
    h = service.client.get("/api/health").json()
    assert h["status"] == "ok" and h["queue"] == "sqlite" and h["workers"] >= 1
    m = service.client.get("/api/methods").json()
    assert "bspline" in m["methods"]
    assert "/api/jobs" in service.client.get("/openapi.json").json()["paths"]


def test_compare_job_gives_a_table_and_the_winner(service):
    if not service.client.get("/api/methods").json()["compare"]:
        pytest.skip("compare is not in this build yet")
    set_id = upload_observations(service.client, synthetic("radial").train.to_json())
    job_id = create_job(service.client, set_id, "compare", {"methods": ["zhang", "fisheye"], "splits": 2})
    job = wait_job(service.client, job_id, 120, service.logs())
    assert job["state"] == "done", job["error"]
    assert job["summary"]["verdict"] in ("zhang", "fisheye")
    table = service.client.get(f"/api/jobs/{job_id}/comparison.csv").text.splitlines()
    assert table[0].startswith("method,rmse") and len(table) == 3
    cal = Calibration.from_json(service.client.get(f"/api/jobs/{job_id}/calibration.json").json())
    assert cal.method == job["summary"]["verdict"]
    # the winner was not asked for by name (it said "as asked (method zhang)")
    assert cal.diagnostics.camera["chosen"].startswith("the comparison's verdict: the best of every method compared")
    r = service.client.post("/api/jobs", json={"set_id": set_id, "method": "compare", "settings": {"splits": "x"}})
    assert r.status_code == 422

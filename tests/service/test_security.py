"""Security in-process (FastAPI's TestClient on the real app, a real SQLite file, no
worker: jobs stay queued, which is what the quota and path tests need).

- FREECAL_TOKEN: every /api request needs the token (header or ?token=), 401 otherwise;
  the page and /docs load without it (they hold no data and must load to ask).
- CORS is closed unless FREECAL_CORS_ORIGINS lists an origin.
- Jobs per client: 429 with advice past FREECAL_MAX_JOBS_PER_CLIENT, also for requests arriving together.
- Downloads and thumbnails take names, never paths: nothing outside a job's or set's folder.
- The service and the 3D view bind loopback by default, and a token keeps the 3D view there;
  /docs needs no internet. (The /viewer proxy over real sockets: test_viewer_proxy.py.)
"""
from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np
import pytest
from fastapi.testclient import TestClient

from backend.app.main import create_app
from backend.base.repository import jobs as job_rows
from backend.base.settings import Settings

from ..conftest import synthetic

TOKEN = "s3cret-token"


def app_client(tmp_path, **overrides) -> TestClient:
    settings = Settings.from_env(env={}, data_dir=tmp_path / "data", viewer=False, **overrides)
    return TestClient(create_app(settings), base_url="http://127.0.0.1")  # a name the Host check allows


@pytest.fixture(scope="module")
def guarded(tmp_path_factory):
    with app_client(tmp_path_factory.mktemp("guarded"), token=TOKEN, cors_origins="http://allowed.example",
                    max_jobs_per_client=2) as c:
        yield c


@pytest.fixture(scope="module")
def open_app(tmp_path_factory):
    with app_client(tmp_path_factory.mktemp("open")) as c:
        yield c


def auth(token: str = TOKEN) -> dict:
    return {"Authorization": f"Bearer {token}"}


OBS = synthetic("radial").train.to_json()
PNG = cv2.imencode(".png", np.full((48, 64), 128, np.uint8))[1].tobytes()


@pytest.mark.parametrize("method, path", [
    ("GET", "/api/health"), ("GET", "/api/sets"), ("GET", "/api/jobs"), ("GET", "/api/methods"),
    ("GET", "/api/viewer"), ("POST", "/api/sets"), ("POST", "/api/jobs"), ("GET", "/api/jobs/x/calibration.json"),
    ("GET", "/api/sets/x/images/a.png/thumbnail"), ("DELETE", "/api/sets/x"),
])
def test_every_api_request_needs_the_token(guarded, method, path):
    r = guarded.request(method, path)
    assert r.status_code == 401
    assert "Authorization: Bearer <token>" in r.json()["detail"] and "FREECAL_TOKEN" in r.json()["detail"]
    assert guarded.request(method, path, headers=auth("wrong")).status_code == 401
    assert guarded.request(method, path, params={"token": "wrong"}).status_code == 401


def test_the_token_opens_the_api_by_header_or_query(guarded):
    assert guarded.get("/api/health", headers=auth()).status_code == 200
    assert guarded.get("/api/health", headers={"authorization": f"bearer {TOKEN}"}).status_code == 200
    assert guarded.get("/api/health", params={"token": TOKEN}).status_code == 200  # <img src>, download links
    r = guarded.post("/api/sets", headers=auth(), files={"files": ("obs.json", __import__("json").dumps(OBS))})
    assert r.status_code == 201


def test_the_page_and_docs_load_without_the_token_and_without_the_internet(guarded):
    page = guarded.get("/")
    assert page.status_code in (200, 404)  # 404 only in a build without frontend/
    docs = guarded.get("/docs")
    assert docs.status_code == 200 and "cdn." not in docs.text and "http" not in docs.text.split("<body>")[-1]
    if "/docs/assets/swagger-ui-bundle.js" in docs.text:  # swagger-ui-bundle installed: served from here
        assert guarded.get("/docs/assets/swagger-ui-bundle.js").status_code == 200
        assert guarded.get("/docs/assets/swagger-ui.css").status_code == 200
    else:
        assert "/openapi.json" in docs.text
    assert guarded.get("/openapi.json").status_code == 200


def test_cors_allows_only_listed_origins(guarded, open_app):
    pre = {"Access-Control-Request-Method": "POST", "Access-Control-Request-Headers": "authorization"}
    ok = guarded.options("/api/jobs", headers={"Origin": "http://allowed.example", **pre})
    assert ok.status_code == 200 and ok.headers["access-control-allow-origin"] == "http://allowed.example"
    bad = guarded.options("/api/jobs", headers={"Origin": "http://evil.example", **pre})
    assert "access-control-allow-origin" not in bad.headers
    r = guarded.get("/api/health", headers={"Origin": "http://evil.example", **auth()})
    assert "access-control-allow-origin" not in r.headers
    # closed by default: no origin at all is allowed
    r = open_app.options("/api/jobs", headers={"Origin": "http://allowed.example", **pre})
    assert "access-control-allow-origin" not in r.headers
    r = open_app.get("/api/health", headers={"Origin": "http://allowed.example"})
    assert r.status_code == 200 and "access-control-allow-origin" not in r.headers


def test_jobs_per_client_answer_429_with_advice(guarded):
    ids = []
    for _ in range(2):  # no worker in-process: they stay queued, so they count
        r = guarded.post("/api/jobs", headers=auth(), json={"observations": OBS})
        assert r.status_code == 201, r.text
        ids.append(r.json()["id"])
    r = guarded.post("/api/jobs", headers=auth(), json={"observations": OBS})
    assert r.status_code == 429 and "limit per client is 2" in r.json()["detail"] and "wait" in r.json()["detail"]
    r = guarded.post("/api/sets", headers=auth(), data={"board": "chessboard:6x4:20mm"},
                     files={"files": ("a.png", b"\x89PNG\r\n\x1a\n" + bytes(100))})
    assert r.status_code == 429, "a set's detection is a job too"
    assert guarded.post(f"/api/jobs/{ids[0]}/cancel", headers=auth()).json()["state"] == "cancelled"
    assert guarded.post("/api/jobs", headers=auth(), json={"observations": OBS}).status_code == 201
    assert guarded.get("/api/health", headers=auth()).status_code == 200  # reads are never limited


@pytest.mark.parametrize("what", ["jobs", "sets"])
def test_requests_arriving_together_stop_at_the_quota(tmp_path, what):
    """Each request (a calibration, or an upload of photos: their detection) holds its place from the quota's check until its job exists: checked and
    counted apart, eight requests at once all passed a limit of two."""
    start = threading.Barrier(8)

    def post(c) -> int:
        start.wait()
        if what == "jobs":
            return c.post("/api/jobs", json={"observations": OBS}).status_code
        return c.post("/api/sets", data={"board": "chessboard:6x4:20mm"}, files={"files": ("a.png", PNG, "image/png")}).status_code

    with app_client(tmp_path, max_jobs_per_client=2) as c:
        with ThreadPoolExecutor(8) as pool:
            codes = sorted(pool.map(post, [c] * 8))
        assert codes == [201] * 2 + [429] * 6
        assert c.get("/api/jobs", params={"kind": "all"}).json()["count"] == 2


def done_job(client: TestClient, headers: dict | None = None) -> tuple[str, bytes]:
    """A job marked done with one result file, as a worker would leave it."""
    r = client.post("/api/jobs", headers=headers or {}, json={"observations": OBS})
    job_id = r.json()["id"]
    ctx = client.app.state.ctx
    attempt = job_rows.claim(ctx.db, job_id, "test")
    (ctx.storage.job_dir(job_id) / "calibration.json").write_text('{"format": "freecal.calibration/1"}')
    job_rows.finish(ctx.db, job_id, attempt, "done", artefacts=["calibration.json"])
    return job_id, ctx.settings.db_path.read_bytes()[:64]


@pytest.mark.parametrize("name", ["..%2F..%2Ffreecal.db", "%2e%2e%2f%2e%2e%2ffreecal.db", "..%5C..%5Cfreecal.db",
                                  "input.json", "%2E%2E", "%2Fetc%2Fpasswd"])
def test_downloads_cannot_reach_outside_the_job(open_app, name):
    job_id, db_head = done_job(open_app)
    assert open_app.get(f"/api/jobs/{job_id}/calibration.json").status_code == 200
    r = open_app.get(f"/api/jobs/{job_id}/{name}")
    # an encoded slash makes it no route of the API (404); a name is looked up among the job's results
    assert r.status_code == 404 and db_head not in r.content and "root:" not in r.text


@pytest.mark.parametrize("path", ["/api/sets/..%2F..%2Ffreecal.db/observations.json",
                                  "/api/sets/x/images/..%2F..%2F..%2Ffreecal.db/thumbnail",
                                  "/api/jobs/..%2Ffreecal.db", "/api/jobs/..%2F..%2Fsets/calibration.json"])
def test_set_and_image_paths_are_ids_not_paths(open_app, path):
    r = open_app.get(path)
    assert r.status_code == 404 and "SQLite" not in r.text


def test_service_and_3d_view_bind_loopback_by_default():
    import inspect

    from backend.cli import build_parser
    from backend.viewer.server import Viewer

    assert build_parser().parse_args(["serve"]).host == "127.0.0.1"
    assert inspect.signature(Viewer.__init__).parameters["host"].default == "127.0.0.1"
    assert Settings.from_env(env={}).viewer_host == "127.0.0.1"


def test_a_token_keeps_the_3d_view_on_loopback(tmp_path):
    """viser cannot check the token: with one set, a public viewer host refuses to start."""
    from dataclasses import replace

    from backend.app.security import check_viewer_exposure
    from calib_core.errors import SettingsError

    base = Settings.from_env(env={}, data_dir=tmp_path)
    check_viewer_exposure(replace(base, token=TOKEN))                                   # loopback: fine
    check_viewer_exposure(replace(base, viewer_host="0.0.0.0"))                         # no token: open anyway
    check_viewer_exposure(replace(base, token=TOKEN, viewer_host="0.0.0.0", viewer=False))  # no 3D view
    with pytest.raises(SettingsError, match="FREECAL_VIEWER_HOST=0.0.0.0 with FREECAL_TOKEN"):
        check_viewer_exposure(replace(base, token=TOKEN, viewer_host="0.0.0.0"))
    with pytest.raises(SettingsError, match="FREECAL_VIEWER=0"):
        create_app(replace(base, token=TOKEN, viewer_host="192.168.1.5"))

"""What a probe of a running service found, each answered 4xx in plain words (never a 500):

- a lone UTF-16 surrogate (the JSON escape \\ud800) in a body or an uploaded JSON file: 422
  naming the field; a string stored before the check never breaks a listing;
- an uploaded JSON file that is a bare null, number or boolean: 422;
- a download of a file a job does not hold (a detection's corners): 404;
- object points far past any board (1e150): 422 at upload, not an internal error in the job;
- too many stored sets: 507 past FREECAL_MAX_SETS;
- a forged X-Forwarded-For from a loopback client does not escape the per-client job quota;
- a body that stops arriving, or trickles in, is answered 408, not held open.

In-process (TestClient, no worker) where the app alone answers; a real `freecal serve` for
what uvicorn decides (forwarded headers, a stalled body).
"""
from __future__ import annotations

import json
import socket
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import pytest
from fastapi.testclient import TestClient

from backend.app.main import create_app
from backend.base.repository import jobs as job_rows
from backend.base.settings import Settings

from ..conftest import synthetic
from .harness import FAST, Service

OBS = synthetic("radial").train.to_json()
JSON = {"content-type": "application/json"}


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    settings = Settings.from_env(env={}, data_dir=tmp_path_factory.mktemp("probe") / "data", viewer=False)
    with TestClient(create_app(settings), base_url="http://127.0.0.1") as c:
        yield c


@pytest.fixture(scope="module")
def ready_set(app):
    r = app.post("/api/sets", files={"files": ("train.json", json.dumps(OBS), "application/json")})
    assert r.status_code == 201, r.text
    return r.json()["id"]


def plain_4xx(r, status: int, *words: str) -> None:
    assert r.status_code == status, r.text
    detail = r.json()["detail"]
    for w in words:
        assert w in detail, f"{w!r} not in {detail!r}"
    assert "Traceback" not in detail and "Error" not in detail


# ---- lone surrogates -------------------------------------------------------------------------
SURROGATE_BODIES = {  # raw JSON text: httpx would refuse to encode the surrogate itself
    "exclude": ('{"set_id": "SET", "method": "zhang", "exclude": ["\\ud800x"]}', "exclude[0]"),
    "set_id": ('{"set_id": "\\ud800"}', "set_id"),
    "rig set_ids": ('{"kind": "rig", "set_ids": ["\\ud800", "x"]}', "set_ids[0]"),
    "settings key": ('{"set_id": "SET", "settings": {"\\udfff": 1}}', "settings"),
}


@pytest.mark.parametrize("case", list(SURROGATE_BODIES))
def test_a_lone_surrogate_in_a_job_body_is_refused_naming_the_field(app, ready_set, case):
    body, field = SURROGATE_BODIES[case]
    before = app.get("/api/jobs").json()["count"]
    r = app.post("/api/jobs", content=body.replace("SET", ready_set), headers=JSON)
    plain_4xx(r, 422, field, "not valid Unicode")
    assert app.get("/api/jobs").json()["count"] == before, "a refused job must not be stored"


def test_a_lone_surrogate_in_other_bodies_is_refused(app, ready_set):
    plain_4xx(app.post("/api/viewer", content='{"job_id": "\\ud800"}', headers=JSON), 422, "job_id", "not valid Unicode")
    plain_4xx(app.post(f"/api/sets/{ready_set}/detect", content='{"board": "\\ud800"}', headers=JSON), 422,
              "board", "not valid Unicode")


def test_a_lone_surrogate_in_an_uploaded_observations_file_is_refused(app):
    text = json.dumps(OBS).replace(f'"name": "{OBS["views"][1]["name"]}"', '"name": "\\udc00.png"', 1)
    r = app.post("/api/sets", files={"files": ("obs.json", text, "application/json")})
    plain_4xx(r, 422, "views[1].name", "not valid Unicode")


def test_a_valid_surrogate_pair_is_text_like_any_other(app):
    doc = json.loads(json.dumps(OBS))
    doc["views"][0]["name"] = "\U0001f4f7.png"  # written as the escape pair \ud83d\udcf7
    r = app.post("/api/sets", files={"files": ("obs.json", json.dumps(doc), "application/json")})
    assert r.status_code == 201, r.text


def test_a_string_stored_before_the_check_never_breaks_reads(app, ready_set):
    ctx = app.app.state.ctx
    job_rows.create(ctx.db, "oldsurrogate", "calibrate", ready_set, "zhang", {"exclude": ["\ud800x"]})
    try:
        for path in ("/api/jobs", f"/api/jobs?set_id={ready_set}", "/api/jobs/oldsurrogate"):
            assert app.get(path).status_code == 200, path
    finally:
        job_rows.delete(ctx.db, "oldsurrogate")


# ---- uploads -----------------------------------------------------------------------------
@pytest.mark.parametrize("body", ["null", "5", "true", '"text"'])
def test_a_json_file_that_is_no_object_is_refused(app, body):
    r = app.post("/api/sets", files={"files": ("x.json", body, "application/json")})
    plain_4xx(r, 422, "JSON object")


def test_object_points_far_past_any_board_are_refused_at_upload(app):
    doc = json.loads(json.dumps(OBS))
    doc["views"][2]["object_points"] = [[x * 1e150, y * 1e150, z] for x, y, z in doc["views"][2]["object_points"]]
    r = app.post("/api/sets", files={"files": ("huge.json", json.dumps(doc), "application/json")})
    plain_4xx(r, 422, "views[2]", "object_points", "at most 1e+09")
    r = app.post("/api/jobs", json={"observations": doc, "method": "zhang"})
    plain_4xx(r, 422, "views[2]", "object_points")


def test_words_for_python_failures(app, ready_set):
    plain_4xx(app.post("/api/sets", data={"files": "abc"}), 422, "expected a file")
    big = json.dumps({"set_id": ready_set, "settings": {"x": 0}}).replace(" 0}", " " + "1" * 5000 + "}")
    r = app.post("/api/jobs", content=big, headers=JSON)
    plain_4xx(r, 422, "more than 4300 digits")
    assert "sys." not in r.json()["detail"]
    for body in ("null", "[]", "5"):  # a job body that is no object: what a job is, not which kind
        plain_4xx(app.post("/api/jobs", content=body, headers=JSON), 422, "a job is a JSON object")


# ---- downloads ---------------------------------------------------------------------------
def test_a_file_the_job_does_not_hold_is_404(app, ready_set):
    ctx = app.app.state.ctx
    job_rows.create(ctx.db, "detectdone", "detect", ready_set, None, {})
    try:
        attempt = job_rows.claim(ctx.db, "detectdone", "test")
        job_rows.finish(ctx.db, "detectdone", attempt, "done", artefacts=["observations.json"])
        r = app.get("/api/jobs/detectdone/observations.json")
        plain_4xx(r, 404, f"/api/sets/{ready_set}/observations.json")
    finally:
        job_rows.delete(ctx.db, "detectdone")


# ---- stored sets -------------------------------------------------------------------------
def test_sets_past_the_limit_answer_507(tmp_path):
    settings = Settings.from_env(env={"FREECAL_MAX_SETS": "2"}, data_dir=tmp_path / "data", viewer=False)
    with TestClient(create_app(settings), base_url="http://127.0.0.1") as c:
        upload = {"files": ("train.json", json.dumps(OBS), "application/json")}
        ids = [c.post("/api/sets", files=upload).json()["id"] for _ in range(2)]
        plain_4xx(c.post("/api/sets", files=upload), 507, "FREECAL_MAX_SETS=2", "delete sets")
        assert c.get("/api/sets").json()["count"] == 2
        assert c.delete(f"/api/sets/{ids[0]}").status_code == 204
        assert c.post("/api/sets", files=upload).status_code == 201


def test_uploads_finishing_together_stop_at_the_limit(tmp_path):
    """Every upload is checked against FREECAL_MAX_SETS before it is read; uploads read at the
    same time all pass that check, and the limit holds only because the set's row is counted
    again as it is written."""
    settings = Settings.from_env(env={"FREECAL_MAX_SETS": "2"}, data_dir=tmp_path / "data", viewer=False)
    upload = {"files": ("train.json", json.dumps(OBS), "application/json")}
    start = threading.Barrier(8)

    def post(c) -> int:
        start.wait()
        return c.post("/api/sets", files=upload).status_code

    with TestClient(create_app(settings), base_url="http://127.0.0.1") as c:
        with ThreadPoolExecutor(8) as pool:
            codes = sorted(pool.map(post, [c] * 8))
        assert codes == [201] * 2 + [507] * 6
        assert c.get("/api/sets").json()["count"] == 2
    assert len(list((tmp_path / "data" / "sets").iterdir())) == 2  # the refused uploads' files are gone


# ---- what uvicorn decides ------------------------------------------------------------------
IDLE = 2.0  # s: FREECAL_BODY_IDLE_SECONDS of the served app (30 by default)


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    root = tmp_path_factory.mktemp("probe-served")
    env = {**FAST, "FREECAL_VIEWER": "0", "FREECAL_MAX_JOBS_PER_CLIENT": "1",
           "FREECAL_BODY_IDLE_SECONDS": str(IDLE)}
    svc = Service(root / "data", root, env, workers=0).start()  # no worker: jobs stay queued and count
    yield svc
    svc.stop()


def test_a_forged_forwarded_address_does_not_escape_the_job_quota(served):
    first = served.client.post("/api/jobs", json={"observations": OBS}, headers={"X-Forwarded-For": "10.0.0.1"})
    assert first.status_code == 201, first.text
    r = served.client.post("/api/jobs", json={"observations": OBS}, headers={"X-Forwarded-For": "10.0.0.2"})
    plain_4xx(r, 429, "limit per client is 1")


def test_a_stalled_body_is_answered_408_and_closed(served):
    with socket.create_connection(("127.0.0.1", served.port), timeout=IDLE + 20) as s:
        s.sendall(f"POST /api/jobs HTTP/1.1\r\nHost: 127.0.0.1:{served.port}\r\nContent-Type: application/json\r\n"
                  "Content-Length: 2000000\r\n\r\n{\"obs".encode())
        start, answer = time.monotonic(), b""
        while chunk := s.recv(4096):  # the server closes the connection after its answer
            answer += chunk
    assert answer.startswith(b"HTTP/1.1 408"), answer[:200]
    assert b"stopped arriving" in answer
    assert time.monotonic() - start < IDLE + 10
    assert served.client.get("/api/health").status_code == 200


def test_a_body_that_trickles_in_is_answered_408_and_closed(served):
    """Ten bytes a second never stalls for IDLE seconds, and at FREECAL_BODY_MIN_RATE (500 bytes a
    second by default) it has used its time after IDLE seconds and a fiftieth of a second a byte."""
    with socket.create_connection(("127.0.0.1", served.port), timeout=IDLE + 20) as s:
        s.sendall(f"POST /api/jobs HTTP/1.1\r\nHost: 127.0.0.1:{served.port}\r\nContent-Type: application/json\r\n"
                  "Content-Length: 2000000\r\n\r\n".encode())
        start, answer = time.monotonic(), b""
        s.settimeout(IDLE / 2)
        while time.monotonic() - start < 4 * IDLE + 10:
            try:
                s.sendall(b" " * 10)
                chunk = s.recv(4096)
            except TimeoutError:
                continue
            except OSError:  # the server closed the connection after its answer
                break
            if not chunk:
                break
            answer += chunk
    assert answer.startswith(b"HTTP/1.1 408"), answer[:200]
    assert b"arrived too slowly" in answer and b"FREECAL_BODY_MIN_RATE" in answer
    assert time.monotonic() - start < 2 * IDLE + 5

"""Issue 17, items 6, 12 and 14 over real sockets: `freecal serve` (no worker) in a subprocess.

- 12: without a token, a page of another site cannot write (403), and a request naming
  another host (DNS rebinding) is refused (400); curl-like clients (no Origin) work.
- 6: the 3D view's websocket checks the Origin at the /viewer proxy, and viser's own port
  takes nothing that did not come through the proxy (token or not).
- 14: nosniff everywhere, a CSP with frame-ancestors on the page, private caching of
  images behind a token, 431 for oversized headers, HEAD wherever GET is, per-image
  reasons without OpenCV's raw text.
"""
from __future__ import annotations

import json
import socket
import time

import cv2
import httpx
import numpy as np
import pytest

from ..conftest import synthetic
from .harness import FAST, Service
from .test_viewer_proxy import frames, listening

pytestmark = pytest.mark.slow

TOKEN = "tok-17_origin"
FRIEND = "http://friend.example"
OBS = json.dumps(synthetic("radial").train.to_json())


@pytest.fixture(scope="module")
def open_svc(tmp_path_factory):
    root = tmp_path_factory.mktemp("origins-open")
    svc = Service(root / "data", root, {**FAST, "FREECAL_VIEWER_PORT": "0", "FREECAL_CORS_ORIGINS": FRIEND},
                  workers=0).start()
    yield svc
    svc.stop()


@pytest.fixture(scope="module")
def guarded(tmp_path_factory):
    root = tmp_path_factory.mktemp("origins-token")
    svc = Service(root / "data", root, {**FAST, "FREECAL_VIEWER_PORT": "0", "FREECAL_TOKEN": TOKEN},
                  workers=0).start()
    yield svc
    svc.stop()


def anyone(svc: Service) -> httpx.Client:
    """A client with no token and no default headers: what another site's page, or curl, sends."""
    return httpx.Client(base_url=f"http://127.0.0.1:{svc.port}", timeout=30)


def png(side: int = 64) -> bytes:
    ok, data = cv2.imencode(".png", np.full((side, side), 128, np.uint8))
    return data.tobytes()


def n_sets(svc: Service) -> int:
    return svc.client.get("/api/sets").json()["count"]


# ---- 12: cross-site writes and DNS rebinding -------------------------------------------
def test_a_page_of_another_site_cannot_write(open_svc):
    before = n_sets(open_svc)
    with anyone(open_svc) as c:
        for headers in ({"Origin": "http://evil.example"}, {"Referer": "http://evil.example/attack.html"},
                        {"Origin": "null"}, {"Origin": f"http://127.0.0.1:{open_svc.port}.evil.example"}):
            r = c.post("/api/sets", headers=headers, data={"board": "chessboard:6x4:20mm"},
                       files={"files": ("obs.json", OBS, "application/json")})
            assert r.status_code == 403, (headers, r.text)
            detail = r.json()["detail"]
            assert "another site" in detail and "FREECAL_CORS_ORIGINS" in detail, detail
        evil = {"Origin": "http://evil.example"}
        assert c.post("/api/jobs", headers=evil, json={"observations": json.loads(OBS)}).status_code == 403
        assert c.delete("/api/sets/anything", headers=evil).status_code == 403
        assert c.post("/api/viewer", headers=evil, json={"job_id": "x"}).status_code == 403
        assert c.get("/api/sets", headers=evil).status_code == 200   # reads: the browser hides them (CORS)
    assert n_sets(open_svc) == before, "a refused upload stored nothing"


def test_the_own_page_listed_origins_and_clients_without_origin_write(open_svc):
    own = f"http://127.0.0.1:{open_svc.port}"
    with anyone(open_svc) as c:
        for headers in ({"Origin": own}, {"Referer": own + "/#set"}, {"Origin": FRIEND}, {}):
            r = c.post("/api/sets", headers=headers, files={"files": ("obs.json", OBS, "application/json")})
            assert r.status_code == 201, (headers, r.text)
        by_name = httpx.post(f"http://localhost:{open_svc.port}/api/sets", headers={"Origin": f"http://localhost:{open_svc.port}"},
                             files={"files": ("obs.json", OBS, "application/json")}, timeout=30)
        assert by_name.status_code == 201, by_name.text


def test_a_host_that_is_not_this_server_is_refused(open_svc):
    with anyone(open_svc) as c:
        for host in ("evil.example:8765", "evil.example", "127.0.0.1.evil.example"):
            r = c.get("/api/health", headers={"Host": host})
            assert r.status_code == 400, (host, r.text)
            assert "FREECAL_ALLOWED_HOSTS" in r.json()["detail"] and "evil.example" in r.json()["detail"]
        assert c.get("/", headers={"Host": "evil.example"}).status_code == 400   # the page too
        for host in (f"127.0.0.1:{open_svc.port}", f"localhost:{open_svc.port}", "localhost", "[::1]:8000",
                     "app.localhost"):
            assert c.get("/api/health", headers={"Host": host}).status_code == 200, host


def test_allowed_hosts_follow_the_settings():
    from backend.app.origins import Allowed
    from backend.base.settings import Settings

    default = Allowed.of(Settings.from_env(env={}))
    assert default.host_ok("127.0.0.1:8000") and default.host_ok("LOCALHOST.") and not default.host_ok("10.0.0.5")
    bound = Allowed.of(Settings.from_env(env={}, host="192.168.1.5"))
    assert bound.host_ok("192.168.1.5:8000") and not bound.host_ok("192.168.1.6") and not bound.host_ok("cal.lan")
    everywhere = Allowed.of(Settings.from_env(env={}, host="0.0.0.0"))
    assert everywhere.host_ok("10.0.0.5:8000") and everywhere.host_ok("[fe80::1]") and not everywhere.host_ok("cal.lan")
    named = Allowed.of(Settings.from_env(env={"FREECAL_ALLOWED_HOSTS": "cal.lan, Cal.Example.com"}))
    assert named.host_ok("cal.lan:8000") and named.host_ok("cal.example.com") and not named.host_ok("evil.example")
    assert Allowed.of(Settings.from_env(env={"FREECAL_ALLOWED_HOSTS": "*"})).host_ok("anything.example")
    # behind a TLS proxy the page is https while the API sees http: the name and port decide
    assert default.origin_ok("https://localhost:8443", "localhost:8443")
    assert not default.origin_ok("http://localhost:8001", "localhost:8000")


# ---- 6: the 3D view's websocket ----------------------------------------------------------
def viser_port(svc: Service) -> int:
    ports = {port for _, port in listening(svc.proc.pid)} - {svc.port}
    assert len(ports) == 1, ports
    return ports.pop()


def refused_directly(port: int, headers: dict | None = None) -> tuple[int, int]:
    """(frames received, close code) of a websocket opened on viser's own port as viser's page would."""
    import viser
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    n = 0
    with connect(f"ws://127.0.0.1:{port}/", subprotocols=[f"viser-v{viser.__version__}"],
                 additional_headers=headers or {}, open_timeout=10) as ws:
        try:
            while True:
                ws.recv(timeout=5)
                n += 1
        except ConnectionClosed:
            return n, ws.close_code
        except TimeoutError:
            return n, -1


@pytest.mark.parametrize("svc_name", ["guarded", "open_svc"])
def test_viser_port_takes_only_the_proxy(svc_name, request):
    svc = request.getfixturevalue(svc_name)
    port = viser_port(svc)
    for headers in ({}, {"Origin": "http://evil.example"}, {"X-Freecal-Viewer-Key": "guess"},
                    {"Origin": f"http://127.0.0.1:{port}"}):
        n, code = refused_directly(port, headers)
        assert (n, code) == (0, 1008), (headers, n, code)
    assert svc.client.get("/api/viewer").json()["clients"] == [], "no tab's scene was built for them"
    through = f"ws://127.0.0.1:{svc.port}/viewer" + (f"?token={TOKEN}" if svc_name == "guarded" else "")
    assert frames(through) >= 1   # the proxy still gets through


def test_the_viewer_proxy_checks_the_websocket_origin(guarded):
    import viser
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    url = f"ws://127.0.0.1:{guarded.port}/viewer?token={TOKEN}"
    for origin in ("http://evil.example", "null"):
        with pytest.raises(InvalidStatus) as refused:
            with connect(url, subprotocols=[f"viser-v{viser.__version__}"], origin=origin, open_timeout=10):
                pass
        assert refused.value.response.status_code == 403
    with connect(url, subprotocols=[f"viser-v{viser.__version__}"], origin=f"http://127.0.0.1:{guarded.port}",
                 open_timeout=10) as ws:
        assert ws.recv(timeout=10)   # the page's own origin: the scene comes


# ---- 14: headers --------------------------------------------------------------------------
def test_nosniff_everywhere_and_a_csp_on_the_page(guarded):
    with anyone(guarded) as c:
        for path in ("/", "/js/main.js", "/api/health", "/openapi.json", "/docs", "/api/jobs/nope"):
            r = c.get(path, params={"token": TOKEN})
            assert r.headers["x-content-type-options"] == "nosniff", path
            assert "frame-ancestors 'self'" in r.headers["content-security-policy"], path
        page = c.get("/").headers["content-security-policy"]
        assert "default-src 'self'" in page and "script-src 'self'" in page and "object-src 'none'" in page
        assert c.get("/api/health").headers["x-content-type-options"] == "nosniff"   # a 401 too
        viewer = c.get("/viewer/", params={"token": TOKEN})
        assert viewer.status_code == 200 and viewer.headers["content-security-policy"] == "frame-ancestors 'self'"


def test_images_behind_a_token_are_cached_privately(guarded):
    r = guarded.client.post("/api/sets", data={"board": "chessboard:6x4:20mm"},
                            files={"files": ("grey.png", png(), "image/png")})
    assert r.status_code == 201, r.text
    thumb = guarded.client.get(f"/api/sets/{r.json()['id']}/images/grey.png/thumbnail")
    assert thumb.status_code == 200 and thumb.headers["content-type"] == "image/jpeg"
    assert thumb.headers["cache-control"].startswith("private")


def raw_request(port: int, head: bytes, pause_after: int | None = None) -> bytes:
    """Send ``head`` (a request's start line and headers) over a socket, optionally in two parts."""
    with socket.create_connection(("127.0.0.1", port), timeout=30) as s:
        if pause_after:
            s.sendall(head[:pause_after])
            time.sleep(0.3)
            s.sendall(head[pause_after:])
        else:
            s.sendall(head)
        answer = b""
        while chunk := s.recv(65536):
            answer += chunk
            if b"\r\n\r\n" in answer and b"}" in answer:
                break
        return answer


@pytest.mark.parametrize("pause_after", [None, 17 * 1024], ids=["whole", "in-parts"])
def test_oversized_headers_answer_431(open_svc, pause_after):
    head = (f"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1:{open_svc.port}\r\nX-Big: {'a' * 20000}\r\n\r\n").encode()
    answer = raw_request(open_svc.port, head, pause_after)
    status, _, rest = answer.partition(b"\r\n")
    assert status.startswith(b"HTTP/1.1 431"), answer[:200]
    assert "headers are larger" in json.loads(rest.partition(b"\r\n\r\n")[2])["detail"]
    assert open_svc.client.get("/api/health").status_code == 200


def test_head_wherever_get_is(open_svc):
    set_id = open_svc.client.post("/api/sets", files={"files": ("obs.json", OBS, "application/json")}).json()["id"]
    for path in ("/", "/api/health", "/api/sets", f"/api/sets/{set_id}", f"/api/sets/{set_id}/observations.json",
                 "/api/jobs", "/api/methods", "/openapi.json"):
        got, head = open_svc.client.get(path), open_svc.client.head(path)
        assert head.status_code == got.status_code == 200, path
        assert head.content == b"" and head.headers["content-type"] == got.headers["content-type"], path
        assert head.headers["content-length"] == str(len(got.content)), path
    assert open_svc.client.head("/api/sets/nope").status_code == 404


def test_per_image_reasons_hold_no_opencv_text():
    import cv2 as cv

    from calib_core.detection.detect_image import failure_reason

    raw = cv.error("OpenCV(5.0.0) /io/opencv/modules/imgcodecs/src/loadsave.cpp:77: error: (-215:Assertion failed) "
                   "pixels <= CV_IO_MAX_IMAGE_PIXELS in function 'validateInputImageSize'")
    for exc in (raw, ValueError("/home/x/secret/path broke"), MemoryError()):
        reason = failure_reason(exc)
        assert "OpenCV(" not in reason and "/io/opencv" not in reason and "/home/" not in reason, reason
        assert "re-save" in reason or "smaller" in reason

"""The 3D view behind the token: real `freecal serve` processes, real HTTP and websockets.

viser cannot check a token, so it listens on loopback only and browsers reach it
through the API's /viewer proxy, which refuses the page and the websocket
handshake without the token (no frame of the scene is sent). A token with viser
configured for a public interface refuses to start.
"""
from __future__ import annotations

import os
import subprocess
from pathlib import Path

import httpx
import pytest

from .harness import FAST, Service, freecal

pytestmark = pytest.mark.slow

TOKEN = "t0k-en_42"
LOOPBACK = {"0100007F", "00000000000000000000000001000000"}   # 127.0.0.1 and ::1 as /proc/net/tcp{,6} write them


@pytest.fixture(scope="module")
def guarded(tmp_path_factory):
    root = tmp_path_factory.mktemp("viewer-proxy")
    svc = Service(root / "data", root, {**FAST, "FREECAL_TOKEN": TOKEN, "FREECAL_VIEWER_PORT": "0"}, workers=0).start()
    yield svc
    svc.stop()


def frames(url: str, seconds: float = 3.0) -> int:
    """Open a websocket as viser's page does (its version as subprotocol) and count the frames received."""
    import viser
    from websockets.sync.client import connect

    n = 0
    with connect(url, subprotocols=[f"viser-v{viser.__version__}"], open_timeout=10) as ws:
        assert ws.subprotocol == f"viser-v{viser.__version__}"
        try:
            while True:
                ws.recv(timeout=seconds)
                n += 1
        except TimeoutError:
            return n


def test_viewer_page_needs_the_token(guarded):
    assert guarded.client.get("/api/viewer").json()["url"] == "/viewer/"
    with httpx.Client(base_url=str(guarded.client.base_url), timeout=30) as anyone:
        r = anyone.get("/viewer/")
        assert r.status_code == 401 and "FREECAL_TOKEN" in r.json()["detail"]
        assert anyone.get("/viewer/", params={"token": "wrong"}).status_code == 401
        page = anyone.get("/viewer/", params={"token": TOKEN})
        assert page.status_code == 200 and "<title>Viser</title>" in page.text
        assert anyone.get("/viewer/", headers={"Authorization": f"Bearer {TOKEN}"}).status_code == 200


def test_viewer_socket_without_the_token_gets_no_scene_data(guarded):
    from websockets.exceptions import InvalidStatus

    base = f"ws://127.0.0.1:{guarded.port}/viewer"
    for url in (base, base + "?token=wrong", base + "?token="):
        with pytest.raises(InvalidStatus) as refused:   # the handshake itself fails: not one frame
            frames(url)
        assert refused.value.response.status_code == 403
    assert frames(f"{base}?token={TOKEN}") >= 1   # with it, viser's messages come through the proxy


def test_viewer_listens_on_loopback_only(guarded):
    """Every listening socket of the API process (uvicorn's and viser's) is on loopback."""
    sockets = listening(guarded.proc.pid)
    assert len(sockets) >= 2, sockets
    assert all(addr in LOOPBACK for addr, _ in sockets), sockets


def test_token_with_viewer_on_a_public_interface_refuses_to_start(tmp_path):
    env = {**os.environ, "FREECAL_TOKEN": TOKEN, "FREECAL_VIEWER_HOST": "0.0.0.0"}
    out = subprocess.run(freecal("serve", "--port", "0", "--data-dir", str(tmp_path / "data")), env=env,
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 2, out.stderr
    assert "FREECAL_VIEWER_HOST=0.0.0.0" in out.stderr and "FREECAL_VIEWER=0" in out.stderr
    assert "Traceback" not in out.stderr and "API on" not in out.stderr


def test_viewer_without_a_token_needs_none(tmp_path):
    svc = Service(tmp_path / "data", tmp_path, {**FAST, "FREECAL_VIEWER_PORT": "0"}, workers=0).start()
    try:
        assert svc.client.get("/viewer/").status_code == 200
        assert frames(f"ws://127.0.0.1:{svc.port}/viewer") >= 1
    finally:
        svc.stop()


def listening(pid: int) -> list[tuple[str, int]]:
    """(hex address, port) of the TCP sockets process ``pid`` listens on, from /proc."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            link = os.readlink(fd)
        except OSError:
            continue
        if link.startswith("socket:["):
            inodes.add(link[8:-1])
    found = []
    for table in ("tcp", "tcp6"):
        for line in Path(f"/proc/{pid}/net/{table}").read_text().splitlines()[1:]:
            f = line.split()
            if f[3] == "0A" and f[9] in inodes:   # 0A: LISTEN
                addr, port = f[1].split(":")
                found.append((addr, int(port, 16)))
    return found

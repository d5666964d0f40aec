"""The capture card in a real browser: Chromium's fake camera plays a video of rendered chessboards
(a .y4m made here from calib_core.synth's renders), the user takes photos, removes one and sends the
rest; the server detects the board in them. And what the card says when there is no camera to use
(refused, absent, or a page that is not a secure context).

Chromium is launched here, with the fake-camera flags, instead of the shared ``browser`` fixture: the
other page tests keep their browser as it is.
"""
from __future__ import annotations

import json
import urllib.request
from pathlib import Path

import pytest

from ..rendered_boards import whole_board_photos
from ..service.harness import wait_for
from .conftest import ARGS, CHROMIUM, page_service, screenshots, wait_until

pytestmark = pytest.mark.slow

service = page_service("capture")
shots = screenshots("capture")


def write_y4m(path: Path, frames: list, fps: int) -> None:
    """``frames`` (BGR, one size, even sides) as a YUV4MPEG2 4:2:0 video, what Chromium's fake camera plays."""
    import cv2

    h, w = frames[0].shape[:2]
    with open(path, "wb") as f:
        f.write(f"YUV4MPEG2 W{w} H{h} F{fps}:1 Ip A1:1 C420jpeg\n".encode())
        for bgr in frames:
            f.write(b"FRAME\n")
            f.write(cv2.cvtColor(bgr, cv2.COLOR_BGR2YUV_I420).tobytes())


@pytest.fixture(scope="module")
def camera(tmp_path_factory):
    """Chromium whose camera is a looping video of four views of a 9x6 chessboard; and the frames' size."""
    import os

    import cv2

    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is in the test extra: make test")
    if not os.access(CHROMIUM, os.X_OK):
        pytest.skip(f"{CHROMIUM} is missing: `make test` installs Debian's chromium (apt-get, as root)")
    folder = tmp_path_factory.mktemp("camera")
    frames = [cv2.imread(str(p)) for p in whole_board_photos(folder / "boards", n=4)]
    video = folder / "boards.y4m"
    write_y4m(video, frames, fps=2)
    flags = ["--use-fake-ui-for-media-stream", "--use-fake-device-for-media-stream",
             f"--use-file-for-fake-video-capture={video}"]
    with sync_api.sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS + flags)
        yield b, (frames[0].shape[1], frames[0].shape[0])
        b.close()


def get(base: str, path: str) -> dict:
    with urllib.request.urlopen(base + path, timeout=10) as r:
        return json.loads(r.read())


def test_take_photos_remove_one_and_send_them_as_a_set(camera, service, shots):
    browser, (w, h) = camera
    base = f"http://127.0.0.1:{service.port}"
    page = browser.new_page(viewport={"width": 1366, "height": 900})
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(base + "/")
    page.wait_for_selector("#method option[value=zhang]", state="attached")
    page.select_option("#method", "zhang")   # the calibration that follows is not what this test is about
    wait_until(page, "document.querySelector('#capture-count').textContent.includes('at most 500')", 10_000)

    page.get_by_role("button", name="Start camera").click()
    wait_until(page, "document.querySelector('#capture-status').textContent.startsWith('Camera on')", 15_000)
    assert f"{w}×{h} px" in page.text_content("#capture-status")   # the device's full size, as asked
    assert page.is_visible("#capture-video") and page.is_hidden("#capture-message")
    assert page.is_hidden("#capture-device-label")   # one camera: no picker

    take = page.get_by_role("button", name="Take photo")
    for k in range(1, 5):
        if k == 3:   # the space bar on the focused preview takes one too
            page.focus("#capture-video")
            page.keyboard.press("Space")
        else:
            take.click()
        wait_until(page, f"document.querySelectorAll('#capture-shots li').length === {k}", 10_000)
        page.wait_for_timeout(300)   # the fake camera moves on to another view now and then
    assert page.text_content("#capture-status").startswith("shot04.png taken")
    page.screenshot(path=shots / "01-four-shots.png")

    page.locator("#capture-shots").scroll_into_view_if_needed()
    page.screenshot(path=shots / "02-strip.png")
    page.get_by_role("button", name="Remove shot02.png").click()
    names = page.locator("#capture-shots li .name").all_text_contents()
    assert names == ["shot01.png", "shot03.png", "shot04.png"]
    assert page.locator("#capture-shots img").count() == 3
    assert page.text_content("#capture-count").startswith("3 photo(s) taken")

    page.get_by_role("button", name="Use these photos").click()
    wait_until(page, "document.querySelector('#capture-status').textContent.includes('sent as a new set')", 30_000)
    assert page.locator("#capture-shots li").count() == 0 and page.is_hidden("#error")
    # the page goes on as for an upload: the set is selected and its detection shown
    wait_until(page, "document.querySelector('#set-progress-label').textContent.startsWith('ready')", 90_000)
    assert page.locator("#images li").count() == 3
    page.get_by_role("button", name="Stop camera").click()
    assert page.is_hidden("#capture-video")
    page.screenshot(path=shots / "03-sent.png", full_page=True)

    sets = get(base, "/api/sets")["sets"]
    assert len(sets) == 1
    one = wait_for(lambda: (s := get(base, f"/api/sets/{sets[0]['id']}"))["state"] == "ready" and s, 60, "set ready")
    images = one["images"]
    assert sorted(i["name"] for i in images) == ["shot01.png", "shot03.png", "shot04.png"]
    assert all((i["width"], i["height"]) == (w, h) for i in images)   # full resolution, not the preview's
    assert sum((i["n_corners"] or 0) > 0 for i in images) >= 2, images
    assert errors == []
    page.close()


@pytest.mark.parametrize("case, script, words", [
    ("refused", "navigator.mediaDevices.getUserMedia = () => "
                "Promise.reject(new DOMException('Permission denied', 'NotAllowedError'));",
     ["camera was refused", "allow it for this page", "upload photos instead"]),
    ("absent", "navigator.mediaDevices.getUserMedia = () => "
               "Promise.reject(new DOMException('Requested device not found', 'NotFoundError'));",
     ["No camera was found", "upload photos instead"]),
    ("insecure", "Object.defineProperty(window, 'isSecureContext', { get: () => false });",
     ["only secure pages", "http://localhost:", "https", "upload photos instead"]),
])
def test_no_camera_to_use_is_said_in_page_words(camera, service, case, script, words):
    browser, _ = camera
    context = browser.new_context()
    context.add_init_script(script)
    page = context.new_page()
    page.goto(f"http://127.0.0.1:{service.port}/")
    page.get_by_role("button", name="Start camera").click()
    page.wait_for_selector("#capture-message:not([hidden])", timeout=10_000)
    message = page.text_content("#capture-message")
    for word in words:
        assert word in message, (case, message)
    assert "Error" not in message    # no DOMException's name, no raw error
    assert page.is_enabled("#capture-start") and page.is_disabled("#capture-take")
    assert page.text_content("#capture-status") == "Camera off." or case == "insecure"
    context.close()


def test_shots_stop_at_the_servers_file_limit(camera, service):
    """The card holds no more shots than a set takes: the limit /api/health reports (here made 2)."""
    browser, _ = camera
    base = f"http://127.0.0.1:{service.port}"
    health = get(base, "/api/health")
    assert health["max_files"] == 500 and health["max_upload_bytes"] > 0
    page = browser.new_page()

    def small_limit(route):
        route.fulfill(status=200, content_type="application/json", body=json.dumps({**health, "max_files": 2}))

    page.route("**/api/health", small_limit)
    page.goto(base + "/")
    wait_until(page, "document.querySelector('#capture-count').textContent.includes('at most 2 per set')", 10_000)
    page.get_by_role("button", name="Start camera").click()
    wait_until(page, "document.querySelector('#capture-status').textContent.startsWith('Camera on')", 15_000)
    for k in (1, 2):
        page.get_by_role("button", name="Take photo").click()
        wait_until(page, f"document.querySelectorAll('#capture-shots li').length === {k}", 10_000)
    page.wait_for_selector("#capture-message:not([hidden])")
    assert "2 photos is the most one set takes" in page.text_content("#capture-message")
    page.get_by_role("button", name="Take photo").click()
    page.wait_for_timeout(500)
    assert page.locator("#capture-shots li").count() == 2
    page.get_by_role("button", name="Remove shot02.png").click()   # room again: the message goes
    assert page.is_hidden("#capture-message")
    page.close()

"""The page and the 3D view in a real browser: Debian's Chromium, headless, driven by Playwright.

One walk through what a user does, against `freecal serve` (API + worker + viser)
in a subprocess: upload OpenCV's left stereo images, watch detection and the
job, read the metrics and a heatmap (with its tooltip), download the
calibration and validate it, open the 3D view and check the scene's nodes
(server side: labels are drawn in the canvas). Screenshots of each step go to
test-artifacts/page/ at 1366x768, and the results also at 1920x1080. Then the
same against a server with FREECAL_TOKEN: the page asks for it once and sends
it with every request, link, thumbnail and the 3D view's websocket.
"""
from __future__ import annotations

import io
import json
import urllib.parse
from pathlib import Path

import pytest

from calib_core import Calibration, synth

from ..conftest import shared_data
from ..service.harness import FAST, Service, wait_for
from .conftest import hover_figure, open_page, page_service, screenshots, wait_until

pytestmark = pytest.mark.slow

# a quick B-spline fit: the page test is about the page, not the method. A field over the
# rational core, so that there is a field to review (on OpenCV's own lens the default
# model choice keeps OpenCV's model alone: the token test below sees that choice).
SETTINGS = {"knots": "uniform", "lambda_smooth": "0.1", "max_iterations": "30",  # intervals: auto
            "bandwidth_factor": "1.2", "time_budget": "60", "core": "rational"}


def fill_settings(page, settings: dict[str, str]) -> None:
    """Open the settings panel and enter ``settings``, whatever each field's kind."""
    page.click("#settings summary")
    for key, value in settings.items():
        if page.eval_on_selector(f"#setting-{key}", "e => e.tagName") == "SELECT":
            page.select_option(f"#setting-{key}", value)
        else:
            page.fill(f"#setting-{key}", value)


service = page_service("page", FREECAL_VIEWER_PORT="0")
shots = screenshots("page")


def test_upload_watch_review_download_and_3d(browser, service, shots, tmp_path):
    import cv2
    import numpy as np

    images = sorted(shared_data("opencv-stereo-9x6").glob("left*.jpg"))
    blank = tmp_path / "no-board.jpg"   # a photo without the board: rejected, with the reason shown
    cv2.imwrite(str(blank), np.full((480, 640, 3), 128, np.uint8))
    base = f"http://127.0.0.1:{service.port}"
    page = browser.new_page(viewport={"width": 1366, "height": 768}, accept_downloads=True)
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(base + "/")
    page.wait_for_selector("#method option[value=bspline]", state="attached")
    page.screenshot(path=shots / "01-upload.png")

    # an error from the API reaches the user as the API's own message
    page.click("#submit")
    page.wait_for_selector("#error:not([hidden])")
    assert "files" in page.text_content("#error")

    page.set_input_files("#files", [str(p) for p in images] + [str(blank)])
    page.select_option("#method", "bspline")
    fill_settings(page, SETTINGS)
    page.screenshot(path=shots / "02-filled.png")
    page.click("#submit")

    wait_until(page, "document.querySelector('#set-progress-label').textContent.startsWith('ready')",
                           timeout=90_000)
    thumbs = page.locator("#images li")
    assert thumbs.count() == len(images) + 1
    assert page.locator("#images li.used").count() >= len(images) - 2
    rejected = page.locator("#images li.rejected", has_text="no-board.jpg")
    assert rejected.count() == 1 and len(rejected.locator("div.rejected").text_content()) > 5  # ✗ and a reason
    page.wait_for_selector("#job-detail:not([hidden])", timeout=30_000)
    page.screenshot(path=shots / "03-detection-and-job.png")

    page.wait_for_selector("#metrics-overall", timeout=120_000)
    page.wait_for_selector("#fig-heatmap canvas")
    assert "px" in page.text_content("#metrics-overall")
    rmse_cell = page.text_content("#metrics-overall tbody td")
    assert rmse_cell.endswith(" px") and 0 < float(rmse_cell.split()[0]) < 1.5
    assert page.locator("#metrics-views tbody tr").count() >= len(images) - 2
    # the knot grid was chosen from the data: its GCV table is shown, one row chosen
    assert page.locator("#metrics-smoothing tbody tr").count() >= 2
    assert page.locator("#metrics-smoothing tbody tr.best").count() == 1
    # the calibration used: Table 7 for raw and rectified boards, a rectified photo, the maps
    page.wait_for_selector("#metrics-quality", timeout=60_000)
    raw, rect = [float(page.text_content(f"#metrics-quality tbody tr:nth-child({i}) td")) for i in (1, 2)]
    assert rect < raw  # rectified board lines are straighter than the photo's
    wait_until(page, "document.querySelector('#rectified-after') && "
                           "document.querySelector('#rectified-after').naturalWidth > 0", timeout=60_000)
    maps = page.request.get(base + page.get_attribute("#downloads a[data-file='maps.npz']", "href"))
    assert maps.ok
    with np.load(io.BytesIO(maps.body())) as npz:
        assert npz["map_x"].dtype == np.float32 and npz["map_x"].shape == npz["map_y"].shape
    # the heatmap is drawn (many colours), and hovering it tells a value with its unit
    colours = page.eval_on_selector("#fig-heatmap canvas", """c => {
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data, seen = new Set();
        for (let i = 0; i < d.length; i += 4 * 37) seen.add(d[i] + ',' + d[i+1] + ',' + d[i+2]);
        return seen.size; }""")
    assert colours > 20
    assert "px" in hover_figure(page, "#fig-heatmap", 0.45, 0.45)
    page.wait_for_selector("#fig-uncertainty", timeout=30_000)
    for fig in ("#fig-vectors", "#fig-field", "#fig-field-vectors", "#fig-knots", "#fig-coverage"):
        assert page.locator(fig).count() == 1, fig
    page.screenshot(path=shots / "04-results.png")
    page.screenshot(path=shots / "05-results-full.png", full_page=True)

    with page.expect_download() as dl:
        page.click("#downloads a[data-file='calibration.json']")
    doc = json.loads(Path(dl.value.path()).read_text())
    cal = Calibration.from_json(doc)
    assert cal.method == "bspline" and len(cal.views) >= len(images) - 2
    # what the user typed in the settings panel is what the calibration used
    used = doc["settings"]
    assert (used["knots"], used["lambda_smooth"], used["bandwidth_factor_used"], used["time_budget"], used["core_used"]) == \
        ("uniform", 0.1, 1.2, 60, "rational")

    # the 3D view: embedded, and its scene (server side) holds the job's objects
    page.click("#open-3d")
    frame = page.wait_for_selector("iframe.viewer-frame")
    frame.scroll_into_view_if_needed()
    job_id = page.get_attribute("#results", "data-job")

    def scene():
        clients = service.client.get("/api/viewer").json()["clients"]
        return next((c for c in clients if c["job_id"] == job_id and c["nodes"]), None)

    shown = wait_for(scene, 60, "the 3D view to connect and draw the job", service.logs())
    nodes = set(shown["nodes"])
    for name in ("/cameras/0/frustum", "/cameras/0/z", "/image_plane/knots", "/residuals/vectors", "/field/dx",
                 "/field/dy"):
        assert name in nodes, name
    boards = {n.split("/")[2] for n in nodes if n.startswith("/boards/") and n.endswith("/corners")}
    assert len(boards) == len(cal.views) and all(f"/boards/{b}/label" in nodes for b in boards)
    assert shown["layers"] == {"Boards": True, "Residual vectors": True, "Knot grid": True, "Field surfaces": True}
    # the embedded view and the new-tab link both name the job on screen (the websocket URL carries it)
    for url in (frame.get_attribute("src"), page.get_attribute("#open-3d-tab", "href")):
        assert f"job={job_id}" in urllib.parse.unquote(url), url
    # a row picked in the per-view table turns its board gold in 3D
    row = page.locator("#metrics-views tbody tr[data-view]").nth(1)
    picked = row.get_attribute("data-view")
    row.locator("th").click()
    assert "view-selected" in row.get_attribute("class")
    wait_for(lambda: (scene() or {}).get("highlighted") == [picked], 20, "the picked view highlighted in 3D",
             service.logs())
    view = frame.content_frame()
    notice = view.locator("[class*=Notification] button")  # viser's software-WebGL notice
    if notice.count():
        notice.first.click()
    # the panel's surface control reaches this tab's scene
    view.get_by_role("combobox", name="Surfaces").click()
    view.get_by_role("option", name="Δy", exact=True).click()
    wait_for(lambda: (scene() or {}).get("component") == "Δy", 20, "the Surfaces control to switch to Δy",
             service.logs())
    # and a layer box hides its layer in this tab's scene (and shows it again)
    boards_box = view.get_by_role("checkbox", name="Boards")
    boards_box.click()
    wait_for(lambda: (scene() or {}).get("layers", {}).get("Boards") is False, 20, "the Boards layer hidden",
             service.logs())
    boards_box.click()
    wait_for(lambda: (scene() or {}).get("layers", {}).get("Boards") is True, 20, "the Boards layer shown",
             service.logs())
    page.wait_for_timeout(3000)  # let WebGL (SwiftShader) draw a few frames before the screenshot
    page.screenshot(path=shots / "06-viewer.png")

    wide = browser.new_page(viewport={"width": 1920, "height": 1080})
    wide.goto(base + "/")
    wide.click(f"#jobs button[data-job='{job_id}']")
    wide.wait_for_selector("#fig-heatmap canvas", timeout=30_000)
    wide.screenshot(path=shots / "07-results-1920.png")
    wide.close()
    page.close()
    assert not errors, errors


TOKEN = "page-t0ken_7"


@pytest.fixture(scope="module")
def guarded(tmp_path_factory):
    root = tmp_path_factory.mktemp("page-token")
    svc = Service(root / "data", root, {**FAST, "FREECAL_VIEWER_PORT": "0", "FREECAL_TOKEN": TOKEN}).start()
    yield svc
    svc.stop()


def test_browser_with_a_token_asks_once_then_sends_it_everywhere(browser, guarded, shots):
    """FREECAL_TOKEN set: opened as /?token=, the page keeps it for the tab (and out of the address bar)
    and every fetch, thumbnail, download and the 3D view's websocket carry it; a tab without it asks once."""
    images = sorted(shared_data("opencv-stereo-9x6").glob("left*.jpg"))[:8]
    base = f"http://127.0.0.1:{guarded.port}"
    page = browser.new_page(viewport={"width": 1366, "height": 768}, accept_downloads=True)
    refused: list[str] = []
    page.on("response", lambda r: refused.append(r.url) if r.status == 401 else None)
    page.goto(f"{base}/?token={TOKEN}")
    page.wait_for_selector("#method option[value=bspline]", state="attached")
    assert "token" not in page.url and page.evaluate("sessionStorage.getItem('freecal.token')") == TOKEN
    assert page.locator("#token-form").count() == 0

    page.set_input_files("#files", [str(p) for p in images])
    assert page.input_value("#method") == "auto"  # the default
    page.click("#submit")
    page.wait_for_selector("#metrics-overall", timeout=180_000)
    # the default model choice: every candidate (parametric models, the paper's field, a field
    # over a core) with its validation error, one chosen, named in words with the rule
    rows = page.locator("#metrics-model-choice tbody tr")
    assert rows.count() == 5 and page.locator("#metrics-model-choice tbody tr.best").count() == 1
    assert "Model chosen:" in page.text_content("#metrics-model-choice caption")
    assert "standard error" in page.text_content("#metrics-model-choice + p")
    page.locator("#metrics-model-choice").locator("xpath=..").screenshot(path=shots / "08-model-choice.png")
    # <img src> and links cannot send headers: they carry ?token=
    first = page.locator("#images img").first
    first.scroll_into_view_if_needed()
    wait_until(page, "(() => { const i = document.querySelector('#images img'); "
                           "return i.complete && i.naturalWidth > 0; })()", timeout=30_000)
    assert f"token={TOKEN}" in first.get_attribute("src")
    hrefs = page.eval_on_selector_all("#downloads a", "as => as.map(a => a.getAttribute('href'))")
    assert hrefs and all(f"token={TOKEN}" in h for h in hrefs)
    with page.expect_download() as dl:
        page.click("#downloads a[data-file='calibration.json']")
    assert Calibration.from_json(json.loads(Path(dl.value.path()).read_text())).method == "auto"
    wait_until(page, "document.querySelector('#rectified-after') && "
                           "document.querySelector('#rectified-after').naturalWidth > 0", timeout=60_000)

    # the 3D view through /viewer: its page and websocket pass the token, and the scene arrives
    page.click("#open-3d")
    frame = page.wait_for_selector("iframe.viewer-frame")
    frame.scroll_into_view_if_needed()
    src = frame.get_attribute("src")
    assert src.startswith("/viewer/?") and f"token={TOKEN}" in src and "websocket=" in src
    job_id = page.get_attribute("#results", "data-job")

    def scene():
        clients = guarded.client.get("/api/viewer").json()["clients"]
        return next((c for c in clients if c["job_id"] == job_id and c["nodes"]), None)

    assert "/cameras/0/frustum" in wait_for(scene, 60, "the 3D view to draw the job", guarded.logs())["nodes"]
    assert not refused, refused   # the tab never met a 401
    page.wait_for_timeout(3000)  # let WebGL draw before the screenshot
    page.screenshot(path=shots / "08-token-viewer.png")

    # a tab without the token: one form, a wrong token is refused, the right one opens the page
    other = browser.new_page()
    other.goto(f"{base}/")
    other.wait_for_selector("#token-form")
    assert other.locator("#token-form").count() == 1
    other.fill("#token-input", "wrong")
    other.click("#token-form button[type=submit]")
    other.wait_for_selector("#token-form:has-text('refused')")
    other.screenshot(path=shots / "09-token-form.png")
    other.fill("#token-input", TOKEN)
    other.click("#token-form button[type=submit]")
    other.wait_for_selector(f"#jobs button[data-job='{job_id}']", timeout=30_000)
    assert other.locator("#token-form").count() == 0
    other.close()
    page.close()


def corners_set(service, name: str) -> str:
    """A set of the radial lens's corners, uploaded as ``name`` through the API; its id."""
    doc = json.dumps(synth.generate("radial").train.to_json())
    created = service.client.post("/api/sets", files={"files": (name, doc, "application/json")})
    assert created.status_code == 201, created.text
    return created.json()["id"]


def showing(browser, service, name: str) -> tuple:
    """The page, showing the set ``name`` (picked in its list), and its script errors."""
    page, errors = open_page(browser, service)
    page.click(f"button[aria-label='set {name}']")
    page.wait_for_selector("#set-detail:not([hidden])")
    return page, errors


def test_a_set_deleted_elsewhere_leaves_the_page_saying_so(browser, service):
    """Deleted through the API (another tab, a script) while the page showed it: the page asked for it every
    second and repeated the API's "no set with id …" in red, its thumbnails and job card frozen."""
    set_id = corners_set(service, "gone.json")
    page, errors = showing(browser, service, "gone.json")
    assert service.client.delete(f"/api/sets/{set_id}").status_code == 204
    page.wait_for_selector("#set-detail[hidden]", state="attached", timeout=10_000)
    said = page.text_content("#error")
    assert "was deleted" in said and "no set with id" not in said
    page.wait_for_timeout(2500)  # the poll loop goes on without asking for it again
    assert page.text_content("#error") == said and not errors
    page.close()


def test_a_set_is_deleted_from_the_page(browser, service):
    """The page had no way to delete a set: a wrong upload stayed, and the server's 507 at
    FREECAL_MAX_SETS ('delete sets you no longer need ... from the page') asked for what it could not do."""
    set_id = corners_set(service, "unwanted.json")
    page, errors = showing(browser, service, "unwanted.json")
    asked: list[str] = []
    page.on("dialog", lambda d: (asked.append(d.message), d.accept()))
    page.click("#set-delete")
    page.wait_for_selector("#set-detail[hidden]", state="attached", timeout=10_000)
    wait_for(lambda: service.client.get(f"/api/sets/{set_id}").status_code == 404, 10, "the set deleted")
    assert asked and "unwanted.json" in asked[0] and "cannot be undone" in asked[0]
    wait_until(page, "!document.querySelector(\"button[aria-label='set unwanted.json']\")", 10_000)
    assert page.is_hidden("#error") and not errors
    page.close()


def test_a_reload_and_the_back_button_keep_what_was_shown(browser, service):
    """A reload showed no set and no calibration, and Back left the page (nothing was in its address)."""
    for name in ("first.json", "second.json"):
        corners_set(service, name)
    page, errors = open_page(browser, service)
    title = "#set-detail-title"
    page.click("button[aria-label='set first.json']")
    wait_until(page, "document.querySelector('#set-detail-title').textContent.includes('first.json')", 10_000)
    page.click("button[aria-label='set second.json']")
    wait_until(page, "document.querySelector('#set-detail-title').textContent.includes('second.json')", 10_000)
    page.reload()
    page.wait_for_selector("#set-detail:not([hidden])", timeout=10_000)
    assert "second.json" in page.text_content(title)
    page.go_back()
    wait_until(page, "document.querySelector('#set-detail-title').textContent.includes('first.json')", 10_000)
    assert page.url.startswith(f"http://127.0.0.1:{service.port}/") and not errors
    page.close()


def test_cancel_says_at_once_that_it_was_asked_for(browser, service):
    """A cancel takes a second or two to reach a running job: the label went on saying "running … about 2 min
    left" and the button stayed live until then."""
    page, errors = open_page(browser, service)
    doc = json.dumps(synth.generate("asymmetric").train.to_json()).encode()
    page.set_input_files("#files", [{"name": "slow.json", "mimeType": "application/json", "buffer": doc}])
    page.select_option("#method", "compare")   # every method, several splits: long enough to cancel
    page.click("#submit")
    wait_until(page, "document.querySelector('#job-progress-label').textContent.startsWith('running')", 60_000)
    page.click("#job-cancel")
    assert page.text_content("#job-progress-label").startswith("cancelling (asked for)")
    assert page.is_disabled("#job-cancel")
    wait_until(page, "document.querySelector('#job-progress-label').textContent.startsWith('cancelled')", 60_000)
    assert page.is_hidden("#job-cancel") and not errors
    page.close()

"""The results page as a calibration engineer reads it (issue 20: parameters, distortion
figures, what was chosen, page words, ETA, phone width, favicon), in real Chromium against
`freecal serve`, on real photo sets (GoPro's wide lens, BabelCalib's >180° fisheye, OpenCV's
stereo left camera) and a rendered one (`freecal synth --images`). Every number on the
camera card is checked against the calibration JSON the page offers for download.
Screenshots go to test-artifacts/results-page/.
"""
from __future__ import annotations

import json
import re
import subprocess
import sys
import time

import pytest

from ..conftest import ROOT, shared_data
from .conftest import hover_figure, open_page, origin, page_service, screenshots, wait_until
from .test_page import fill_settings

pytestmark = pytest.mark.slow

PHONE = {"width": 375, "height": 740}
DESKTOP = {"width": 1366, "height": 768}
HEX_ID = re.compile(r"\b[0-9a-f]{12,}\b")


service = page_service("results-page", FREECAL_VIEWER="0")
shots = screenshots("results-page")


def upload(page, files, board: tuple[int, int, float], method: str = "auto", settings: dict | None = None) -> None:
    page.set_input_files("#files", [str(p) for p in files])
    page.fill("#board-cols", str(board[0]))
    page.fill("#board-rows", str(board[1]))
    page.fill("#board-square", str(board[2]))
    page.select_option("#method", method)
    if settings:
        fill_settings(page, settings)
    page.click("#submit")


def results(page, timeout: float) -> dict:
    """Wait for the camera card; the calibration JSON the page links to, as a download would give it."""
    page.wait_for_selector("#camera-params", timeout=timeout)
    href = page.get_attribute("#downloads a[data-file='calibration.json']", "href")
    return json.loads(page.request.get(origin(page) + href).text())


def shown_number(text: str) -> float:
    return float(text.replace("±", "").replace("−", "-").strip())


def assert_card_equals_json(page, doc: dict) -> dict:
    """Every parameter, ± and field of view on the card is the calibration JSON's, to the digits shown."""
    camera = doc["diagnostics"]["camera"]
    rows = page.eval_on_selector_all("#camera-params tbody tr[data-name]", """rs => rs.map(r => ({
        name: r.dataset.name, value: r.querySelector('td.value').textContent,
        std: r.querySelector('td.std').textContent }))""")
    assert [r["name"] for r in rows] == [p["name"] for p in camera["parameters"]]
    for row, p in zip(rows, camera["parameters"], strict=True):
        digits = len(row["value"].split(".")[1]) if "." in row["value"] and "e" not in row["value"] else None
        tolerance = 0.5 * 10 ** -digits if digits is not None else abs(p["value"]) * 0.05
        assert abs(shown_number(row["value"]) - p["value"]) <= tolerance * 1.001, (row, p)
        if p["std"] is None:
            assert row["std"] == "—"
        else:
            assert abs(shown_number(row["std"]) - p["std"]) <= max(0.05 * p["std"], tolerance), (row, p)
    # the card's intrinsics are the calibration's own
    k = doc["intrinsics"]
    for name in ("fx", "fy", "cx", "cy"):
        assert next(p for p in camera["parameters"] if p["name"] == name)["value"] == k[name]
    fov = page.text_content("#camera-fov")
    for name, value in camera["field_of_view_deg"].items():
        far = camera["no_ray_beyond_px"].get(name)
        assert (f"{value:.1f}° {name}" if value is not None else
                f"{name}: no ray past {far:.0f} px from the principal point") in fov
    assert page.text_content("#verdict-text") == camera["verdict"]["text"]
    assert camera["model"] in page.text_content("#camera-model")
    return camera


def watch_progress(page) -> None:
    """Keep every text the set's and the job's progress lines show, as they change."""
    page.evaluate("""() => { window.progressLines = [];
        for (const id of ['set-progress-label', 'job-progress-label']) {
            const line = document.getElementById(id);
            new MutationObserver(() => window.progressLines.push(id + ': ' + line.textContent))
                .observe(line, {childList: true, characterData: true, subtree: true}); } }""")


def assert_said_time_left(page) -> None:
    lines = page.evaluate("window.progressLines")
    assert any(re.search(r"(a few seconds|about \d+ (s|min)) left", t) for t in lines), "\n".join(lines)


def assert_fits_the_screen(page, what: str) -> None:
    width = page.evaluate("document.documentElement.scrollWidth")
    wide = page.evaluate("""() => [...document.querySelectorAll('main *')]
        .filter(e => e.getBoundingClientRect().right > window.innerWidth + 1 && e.offsetParent !== null)
        .slice(0, 5).map(e => e.tagName + '#' + e.id + '.' + e.className + ' ' + Math.round(e.getBoundingClientRect().right))""")
    assert width <= page.viewport_size["width"] + 1, f"{what}: the page is {width} px wide on a 375 px screen: {wide}"


def test_gopro_camera_card_distortion_as_angles_words_and_progress(browser, service, shots):
    images = sorted(shared_data("gopro-hero3-wide-15x9").glob("*.JPG"))
    page, errors = open_page(browser, service, viewport=DESKTOP, accept_downloads=True)
    # a favicon, served
    icon = page.get_attribute("link[rel=icon]", "href")
    assert page.request.get(origin(page) + "/" + icon.lstrip("/")).headers["content-type"].startswith("image/svg")
    # page words: no schema-speak for an upload without photos
    page.click("#submit")
    page.wait_for_selector("#error:not([hidden])")
    said = page.text_content("#error")
    assert "Choose the photos first" in said and "invalid request" not in said and "/docs" not in said
    # a one-line help on every setting, of every method
    for method in ("auto", "bspline", "compare", "zhang"):
        page.select_option("#method", method)
        assert page.text_content("#method-help").strip()
        missing = page.eval_on_selector_all("#upload-form input:not([type=file]), #upload-form select", """es => es
            .filter(e => { const h = document.getElementById(e.getAttribute('aria-describedby') || '');
                           return !h || !h.textContent.trim(); }).map(e => e.id)""")
        assert missing == [], f"settings without help under method {method}: {missing}"
    page.screenshot(path=shots / "01-upload-help.png", full_page=True)

    watch_progress(page)
    started = time.monotonic()
    upload(page, images, (15, 9, 26))
    doc = results(page, 240_000)
    # upload → results → download, as a new user goes: the calibration saved by its link within a minute
    with page.expect_download() as download:
        page.click("#downloads a[data-file='calibration.json']")
    saved = json.loads(open(download.value.path()).read())
    walk = time.monotonic() - started
    assert saved["format"] == "freecal.calibration/1" and walk < 60, f"upload to download took {walk:.0f} s"
    # the set's progress never runs backwards (its board-size check once restarted it at 0 %)
    shown = [float(m[1]) for t in page.evaluate("window.progressLines")
             if (m := re.match(r"set-progress-label: detecting · (\d+) %", t))]
    assert shown == sorted(shown), shown
    camera = assert_card_equals_json(page, doc)
    # what was chosen, in words: the heading names the model (never another method's code name)
    title = page.text_content("#results-title")
    assert doc["settings"]["chosen"] == "fisheye" and "Kannala-Brandt" in title and "bspline" not in title
    assert camera["field"] is None and page.locator("#fig-knots").count() == 0   # no field: no knot grid
    assert page.locator("#camera-field").count() == 0
    assert page.text_content("#metrics-overall tbody td:nth-last-child(2)") == "8"  # fitted parameters, as KB has
    # the wide lens reads as angles against the equidistant lens, on a scale of degrees
    fig = page.locator("#fig-field")
    assert fig.get_attribute("data-view") == "angle:dtheta" and fig.get_attribute("data-unit") == "°"
    assert 0.5 < float(fig.get_attribute("data-scale")) < 15   # not ±585 px
    assert "angle off axis" in page.text_content("#fig-field figcaption")
    assert page.locator("#fig-field-vectors").count() == 0  # pinhole offsets of a wide lens: not drawn
    assert "° off axis" in hover_figure(page, "#fig-field", 0.2, 0.3)
    # words: no "Table 7", no hex id where a name exists
    page.wait_for_selector("#metrics-quality", timeout=60_000)
    text = page.text_content("main")
    assert "Table 7" not in text
    job_id = page.get_attribute("#results", "data-job")
    for where in ("#jobs", "#sets", "#job-detail-title", "#results-title"):
        assert not HEX_ID.search(page.text_content(where)), (where, page.text_content(where))
    assert "auto → Kannala-Brandt" in page.text_content(f"#jobs button[data-job='{job_id}']")
    page.locator("#camera").screenshot(path=shots / "02-gopro-camera-card.png")
    page.screenshot(path=shots / "03-gopro-results.png", full_page=True)
    page.close()
    assert not errors, errors


def test_babelcalib_on_a_phone_field_over_its_core_and_no_overflow(browser, service, shots):
    root = shared_data("babelcalib-ov-plane-fisheye")
    images = sorted((root / "train").glob("*.png"))
    page, errors = open_page(browser, service, viewport=PHONE, accept_downloads=True)
    assert_fits_the_screen(page, "the upload form")
    page.screenshot(path=shots / "05-phone-upload.png", full_page=True)
    watch_progress(page)
    upload(page, images, (22, 22, 7.5))
    doc = results(page, 420_000)
    assert_said_time_left(page)
    camera = assert_card_equals_json(page, doc)
    # past 180°: the frame's midline leaves the image circle, the corners' reach is said instead
    assert camera["max_corner_angle_deg"] > 90 and "off axis" in page.text_content("#camera-fov")
    if doc["distortion"]["type"] == "hybrid":  # auto's usual choice here: a field over Kannala-Brandt
        assert "over the Kannala-Brandt" in page.text_content("#results-title")
        assert page.get_attribute("#fig-field", "data-view") == "field:dx"  # the field's own part, in px
        assert float(page.get_attribute("#fig-field", "data-scale")) < 20   # not ±8 211 px
        assert page.locator("#fig-knots").count() == 1 and page.locator("#camera-field").count() == 1
        held = [p for p in camera["parameters"] if p["status"] == "held"]
        assert held and all(page.text_content(f"#camera-params tr[data-name='{p['name']}'] td.std") == "—" for p in held)
    else:
        assert page.get_attribute("#fig-field", "data-view") == "angle:dtheta"
    page.wait_for_selector("#metrics-quality", timeout=60_000)
    assert_fits_the_screen(page, "the results")
    page.screenshot(path=shots / "06-phone-results.png", full_page=True)
    page.close()
    assert not errors, errors


def test_rendered_set_and_opencv_stereo_field_table_and_verdict_advice(browser, service, shots, tmp_path):
    # a rendered set (freecal synth --images): the paper's field, with its knot grid and smoothing table
    subprocess.run([sys.executable, "-m", "backend.cli", "synth", "--kind", "radial", "--views", "6", "--images",
                    "-o", str(tmp_path / "synth")], cwd=ROOT, check=True, capture_output=True)
    page, errors = open_page(browser, service, viewport=DESKTOP, accept_downloads=True)
    upload(page, sorted((tmp_path / "synth" / "images").glob("*.png")), (22, 22, 50), "bspline",
           {"knots": "uniform", "intervals": "4x4", "max_iterations": "30"})
    doc = results(page, 300_000)
    camera = assert_card_equals_json(page, doc)
    assert camera["field"] and page.locator("#fig-knots").count() == 1 and page.locator("#camera-field").count() == 1
    assert next(p for p in camera["parameters"] if p["name"] == "skew")["status"] == "fitted"  # the field's model has skew
    assert "B-spline field over the pinhole" in page.text_content("#results-title")
    # px² next to px, explained
    smoothing = page.locator("#metrics-smoothing")
    assert "px²" in smoothing.text_content() and "√(px² / 2)" in page.text_content("#metrics-smoothing + p")
    assert "as rms per axis [px]" in smoothing.text_content()
    page.screenshot(path=shots / "07-rendered-results.png", full_page=True)

    # OpenCV's left camera, 640 × 480, corners in the middle only: the verdict says where to add views
    page.goto(origin(page) + "/")   # a fresh page, not the one its address shows
    page.wait_for_selector("#method option[value=auto]", state="attached")
    upload(page, sorted(shared_data("opencv-stereo-9x6").glob("left*.jpg")), (9, 6, 25), "zhang")
    wait_until(page, "document.querySelector('#results-title').textContent.includes('5 coefficients')",
               timeout=180_000)
    doc = results(page, 60_000)
    camera = assert_card_equals_json(page, doc)
    assert page.get_attribute("#fig-field", "data-view") == "pinhole:dx"   # a narrow lens: pixels against the pinhole
    advice = camera["verdict"]["advice"]
    assert any(a.startswith("add views at the ") for a in advice)
    assert "add views at the" in page.text_content("#verdict-text")
    assert "copy" in page.text_content("#camera .matrix summary")
    page.click("#camera .matrix summary")
    numbers = [float(x) for x in re.findall(r"-?\d+\.?\d*(?:e-?\d+)?", page.text_content("#camera-matrix"))]
    k, dist = doc["intrinsics"], doc["distortion"]["coefficients"]
    expected = [k["fx"], k["skew"], k["cx"], 0, k["fy"], k["cy"], 0, 0, 1, *dist]
    assert numbers == pytest.approx(expected, rel=1e-9, abs=1e-12)   # K and dist as OpenCV takes them, to copy
    page.locator("#camera").screenshot(path=shots / "08-opencv-camera-card.png")
    page.close()
    assert not errors, errors

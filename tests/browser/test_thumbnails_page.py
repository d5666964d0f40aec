"""The set's thumbnails and its coverage advice in real Chromium against `freecal serve`
(issue 20, points 8 and 9).

Four GoPro photos under long names (two alike but for their middle), one of them blurred a
little and one blurred past what detection accepts: every used thumbnail has its detected
corners drawn over it (as many as the set reports), the names shown differ and the full name
is in the tooltip, the sharpness note says sharp / a little soft / blurry in agreement with
the ✓ or ✗, and a click opens the 640 px photo with its corners, which Escape (or Close)
closes. Then three BabelCalib fisheye photos: the coverage advice names stretches of the
image circle's edge, never the frame's black corners, and the coverage map draws the circle.
Screenshots go to test-artifacts/thumbnails/.
"""
from __future__ import annotations

import cv2
import pytest

from ..conftest import shared_data
from .conftest import open_page, origin, page_service, screenshots, wait_until

pytestmark = pytest.mark.slow

service = page_service("thumbnails-page", FREECAL_VIEWER="0")
shots = screenshots("thumbnails")

LONG = "calibration-gopro-hero3-wide-session-2024-05-07-"
NAMES = (LONG + "3D_L0478.JPG", LONG + "3D_L0479.JPG",                # alike but for their end
         "calibration-photo-left-board-0001-gopro.JPG",               # alike but for their middle
         "calibration-photo-right-board-0001-gopro.JPG")
BLUR = {2: 2.5, 3: 4.0}   # photo index → Gaussian σ (px): edges ~7 px wide (soft, used), ~11 px (too blurry)


def jpeg(path, sigma: float | None) -> bytes:
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if sigma:
        img = cv2.GaussianBlur(img, (0, 0), sigma)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 95])
    assert ok
    return buf.tobytes()


def submit(page, files, board: tuple[int, int, float], method: str) -> None:
    page.set_input_files("#files", files)
    page.fill("#board-cols", str(board[0]))
    page.fill("#board-rows", str(board[1]))
    page.fill("#board-square", str(board[2]))
    page.select_option("#method", method)
    page.click("#submit")


def shown_set(page) -> dict:
    """The set the page shows, as the API gives it."""
    name = page.get_attribute("#images li[data-name]", "data-name")
    sets = page.request.get(origin(page) + "/api/sets").json()
    for s in sets["sets"]:
        full = page.request.get(origin(page) + f"/api/sets/{s['id']}").json()
        if any(im["name"] == name for im in full["images"]):
            return full
    raise AssertionError(f"no set holds {name}")


def test_thumbnails_corners_enlarged_view_names_and_sharpness(browser, service, shots):  # noqa: F811
    photos = sorted(shared_data("gopro-hero3-wide-15x9").glob("*.JPG"))[:4]
    files = [{"name": n, "mimeType": "image/jpeg", "buffer": jpeg(p, BLUR.get(k))}
             for k, (n, p) in enumerate(zip(NAMES, photos, strict=True))]
    page, errors = open_page(browser, service, viewport={"width": 1366, "height": 900})
    submit(page, files, (15, 9, 26), "zhang")
    wait_until(page, "document.querySelector('#set-progress-label').textContent.startsWith('ready')", 180_000)
    wait_until(page, "document.querySelectorAll('#images li[data-corners]').length >= 3", 30_000)
    s = shown_set(page)
    reports = {im["name"]: im for im in s["images"]}

    # every used photo has its corners drawn, as many as the set reports; the rejected one none
    items = page.eval_on_selector_all("#images li[data-name]", """ls => ls.map(li => {
        const c = li.querySelector('canvas.corner-overlay'), d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        let painted = 0; for (let i = 3; i < d.length; i += 4) if (d[i] > 0) painted++;
        const sharp = li.querySelector('.sharpness');
        return { name: li.dataset.name, corners: li.dataset.corners ?? null, painted,
                 label: li.querySelector('.name').textContent, title: li.querySelector('.name').title,
                 tick: li.querySelector('.tick').textContent,
                 overflows: li.querySelector('.name').scrollWidth > li.querySelector('.name').clientWidth,
                 sharpness: sharp && sharp.dataset.verdict, note: sharp && sharp.textContent }; })""")
    assert [i["name"] for i in items] == list(NAMES)
    for item in items:
        im = reports[item["name"]]
        if im["status"] == "used":
            assert item["corners"] == str(im["n_corners"]) and im["n_corners"] > 100, item
            assert item["painted"] > 200, item                  # dots, visibly, not an empty canvas
        else:
            assert item["corners"] is None and item["painted"] == 0, item

    # names: shown shortened in the middle, all different, the full name in the tooltip
    labels = [i["label"] for i in items]
    assert len(set(labels)) == len(labels), labels
    assert all(i["title"] == i["name"] for i in items)
    assert all(len(i["label"]) < len(i["name"]) and "…" in i["label"] for i in items), labels
    assert all(i["label"].endswith(i["name"][-6:]) for i in items), labels   # the numbering end stays
    assert not any(i["overflows"] for i in items), items                    # and is seen, not cut by the box

    # the sharpness note agrees with the tick: sharp photos used, the soft one used, the blurry one rejected
    by_name = {i["name"]: i for i in items}
    assert [by_name[n]["sharpness"] for n in NAMES] == ["sharp", "sharp", "soft", "blurry"], items
    for item in items:
        used = item["tick"].startswith("✓")
        assert used == (item["sharpness"] != "blurry"), item
        assert item["note"].startswith({"sharp": "sharp: edges", "soft": "a little soft: edges",
                                        "blurry": "blurry: edges"}[item["sharpness"]]), item
        assert "(< 3: sharp)" not in item["note"]
    assert by_name[NAMES[3]]["tick"] == "✗ too blurry"
    page.locator("#set-detail").screenshot(path=shots / "01-thumbnails-with-corners.png")

    # a click enlarges the photo with its corners; Escape closes it and focus returns to the thumbnail
    first = page.locator("#images li[data-name] .thumb-open").first
    first.click()
    page.wait_for_selector("#image-dialog[open]")
    dialog = page.locator("#image-dialog")
    assert dialog.get_attribute("data-corners") == str(reports[NAMES[0]]["n_corners"])
    assert "size=640" in dialog.locator("img").get_attribute("src")
    assert page.text_content("#image-dialog-title") == NAMES[0]
    wait_until(page, "document.querySelector('#image-dialog img').complete && "
                     "document.querySelector('#image-dialog img').naturalWidth === 640", 20_000)
    page.screenshot(path=shots / "02-enlarged.png")
    page.keyboard.press("Escape")
    wait_until(page, "!document.querySelector('#image-dialog').open", 5_000)
    assert page.evaluate("document.activeElement.classList.contains('thumb-open')")
    # the Close button too (the blurry photo: no corners drawn, its tick shown)
    page.locator("#images li[data-name] .thumb-open").nth(3).click()
    page.wait_for_selector("#image-dialog[open]")
    assert dialog.get_attribute("data-corners") == "0" and "too blurry" in dialog.text_content()
    dialog.get_by_role("button", name="Close").click()
    wait_until(page, "!document.querySelector('#image-dialog').open", 5_000)
    assert not errors, errors
    page.close()


def test_fisheye_coverage_advice_stays_inside_the_image_circle(browser, service, shots):  # noqa: F811
    photos = sorted((shared_data("babelcalib-ov-plane-fisheye") / "train").glob("*.png"))[:3]
    page, errors = open_page(browser, service, viewport={"width": 1366, "height": 900})
    submit(page, [str(p) for p in photos], (22, 22, 7.5), "fisheye")
    wait_until(page, "document.querySelector('#set-progress-label').textContent.startsWith('ready')", 240_000)
    s = shown_set(page)
    circle = s["coverage"]["image_circle"]
    assert abs(circle["cx"] - 648) < 10 and abs(circle["cy"] - 404) < 10 and abs(circle["radius"] - 480) < 10
    advice = [w for w in (page.text_content("#set-warnings") or "").split("add views with the board in those regions")
              if "no corners" in w]
    assert advice, page.text_content("#set-warnings")
    for text in advice:
        assert "no corners near the edge of the image circle at the" in text, text
        assert " corner" not in text.split("no corners", 1)[1] and "edge of the image:" not in text, text
    page.locator("#set-detail").screenshot(path=shots / "03-fisheye-advice.png")
    # the coverage map draws the circle (the figure comes with the calibration's results)
    page.wait_for_selector("#fig-coverage", timeout=240_000)
    drawn = [float(x) for x in page.get_attribute("#fig-coverage", "data-image-circle").split()]
    assert drawn == [circle["cx"], circle["cy"], circle["radius"]]
    note = page.text_content("#fig-coverage .note")
    assert "inside the image circle" in note and "Grey: outside the lens's image circle" in note
    assert "corner," not in note and "corner." not in note
    page.locator("#fig-coverage").scroll_into_view_if_needed()
    page.locator("#fig-coverage").screenshot(path=shots / "04-fisheye-coverage-map.png")
    assert not errors, errors
    page.close()

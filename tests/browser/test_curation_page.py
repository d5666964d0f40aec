"""Curation, board sizes and forgiving uploads on the page, in Debian's Chromium (Playwright),
against `freecal serve`: what the user sees and clicks.

GoPro's 24 photos dropped with a stray BabelCalib `.orpc` and an empty file, the board given
as 9 × 6 (another board's size): the two files are listed as skipped with why, the job waits
for the detection, the detection fails in page words counting the 24 photos and offers
"Found 15 × 9 inner corners in 24 of 24 photos: use that?"; its button detects again and
calibrates. Then the per-view table: sorted by rmse, the flagged views unticked and the set
re-run with another method, no upload; the set's calibrations side by side. Last, rendered
photos of a 9 × 6 board given by its squares (10 × 7): the size is suggested on a ready set.
Screenshots go to test-artifacts/curation/.
"""
from __future__ import annotations

import pytest

from ..conftest import shared_data
from ..rendered_boards import whole_board_photos
from .conftest import page_service, screenshots, wait_until

pytestmark = pytest.mark.slow


service = page_service("curation-page", FREECAL_VIEWER="0")
shots = screenshots("curation")


def text(page, selector: str) -> str:
    return page.text_content(selector) or ""


def set_board(page, cols: int, rows: int, square: float) -> None:
    page.fill("#board-cols", str(cols))
    page.fill("#board-rows", str(rows))
    page.fill("#board-square", str(square))


def test_wrong_board_size_skipped_files_and_curation_on_gopro(browser, service, shots, tmp_path):  # noqa: F811
    photos = sorted(shared_data("gopro-hero3-wide-15x9").glob("*.JPG"))
    orpc = next(iter(sorted((shared_data("babelcalib-ov-plane-fisheye") / "train").glob("*.orpc"))))
    empty = tmp_path / "empty.jpg"
    empty.write_bytes(b"")
    page = browser.new_page(viewport={"width": 1366, "height": 768})
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(f"http://127.0.0.1:{service.port}/")
    page.wait_for_selector("#method option[value=auto]", state="attached")
    set_board(page, 9, 6, 26)
    page.set_input_files("#files", [str(p) for p in photos] + [str(orpc), str(empty)])
    page.click("#submit")

    # the drop kept the photos and says which files it skipped, and why, in page words
    page.wait_for_selector("#skipped-files")
    skipped = text(page, "#skipped-files")
    assert "2 files of the upload were not used" in skipped and orpc.name in skipped and "empty.jpg" in skipped
    assert ".orpc files are not read" in skipped and "empty (0 bytes)" in skipped
    assert page.locator("#images li").count() == len(photos)
    # the job was created at once and waits for the corners
    wait_until(page, "document.querySelector('#job-progress-label').textContent.includes("
                     "\"waiting for the set's corner detection\")", 30_000)
    page.screenshot(path=shots / "01-skipped-and-waiting.png")

    # 9 x 6 is not this board: the detection fails saying so, counting the photos uploaded, and suggests its size
    page.wait_for_selector("#board-suggestion", timeout=240_000)
    label = text(page, "#set-progress-label")
    assert label.startswith("failed") and "found in none of the 24 photos" in label, label
    assert "--board" not in label and "--board" not in text(page, "#images")
    hint = text(page, "#board-suggestion")
    assert "Found 15 × 9 inner corners in 24 of 24 photos: use that?" in hint, hint
    wait_until(page, "document.querySelector('#job-progress-label').textContent.includes('corner detection failed')",
               30_000)
    page.locator("#set-detail").screenshot(path=shots / "02-board-size-suggested.png")

    page.click("#use-board-size")   # detects again with 15 x 9 and calibrates, no new upload
    wait_until(page, "document.querySelector('#board-cols').value === '15' && "
                     "document.querySelector('#board-rows').value === '9'", 30_000)   # the form follows
    wait_until(page, "document.querySelector('#set-progress-label').textContent.startsWith('ready')", 240_000)
    assert page.locator("#board-suggestion").count() == 0
    page.wait_for_selector("#metrics-views tbody tr", timeout=240_000)

    # the per-view table: every view, corners kept of found, sortable, the suspicious ones flagged with why
    rows = page.locator("#metrics-views tbody tr")
    assert rows.count() == 24
    assert "/ 135" in text(page, "#metrics-views tbody tr:first-child td:nth-child(3)")
    page.click("#metrics-views button[data-sort=rmse]")
    rmse = [float(t.split()[0]) for t in page.locator("#metrics-views tbody tr td:nth-child(4)").all_text_contents()]
    assert rmse == sorted(rmse, reverse=True)
    flagged = page.locator("#metrics-views tbody tr.flagged")
    assert flagged.count() >= 1
    assert "thrown out as outliers" in (flagged.first.locator(".flag").first.get_attribute("title") or "")
    assert "thrown out as outliers" in text(page, "#flag-details")
    page.locator("#curation").screenshot(path=shots / "03-views-flagged.png")

    # leave the flagged views out, choose another method in card 1, re-run on the same set
    names = flagged.evaluate_all("rows => rows.map(r => r.dataset.view)")
    page.click("#untick-flagged")
    assert f"without {len(names)} view" in text(page, "#rerun-count")
    page.select_option("#method", "zhang")
    first = text(page, "#results-title")
    page.click("#rerun")
    wait_until(page, f"document.querySelector('#results-title').textContent !== {first!r} && "
                     "document.querySelector('#results-title').textContent.includes('OpenCV model, 5 coefficients')", 120_000)
    page.wait_for_selector("#metrics-views tbody tr.excluded")
    left_out = page.locator("#metrics-views tbody tr.excluded").evaluate_all("rows => rows.map(r => r.dataset.view)")
    assert sorted(left_out) == sorted(names)
    assert page.locator("#metrics-views tbody tr").count() == 24   # the left-out views stay listed, unticked
    # the set's calibrations side by side: the re-run with its method and the views it left out
    page.wait_for_selector("#set-jobs-table")
    table = text(page, "#set-jobs-table")
    assert "zhang" in table and f"({len(names)} left out)" in table and "auto" in table
    assert page.locator("#set-jobs-table tbody tr").count() == 3   # the failed first job, auto, zhang
    page.locator("#set-jobs").scroll_into_view_if_needed()
    page.screenshot(path=shots / "04-rerun-side-by-side.png")

    # the re-run against the auto calibration: the projection difference, as `freecal diff` computes it
    options = page.locator("#compare-with option:not([value=''])")
    assert options.count() == 1 and "auto" in options.first.text_content()   # the failed job is no calibration
    other = options.first.get_attribute("value")
    page.select_option("#compare-with", other)
    page.wait_for_selector("#fig-diff canvas", timeout=60_000)
    shown = page.evaluate("location.origin")
    shown_job = page.locator("#set-jobs-table tr.best").get_attribute("data-job")
    api = page.request.get(f"{shown}/api/jobs/{shown_job}/figures/diff/{other}").json()
    median = text(page, "#diff-summary tr[data-region='covered by both'] td.median")
    assert median == f"{api['covered']['median']:.3f} px", (median, api["covered"])
    assert api["covered"]["median"] < 2.0   # one lens, two models: pixels apart at most where both had corners
    assert "Rotation between the camera frames" in text(page, "#diff-summary")
    page.locator("#compare-slot").screenshot(path=shots / "05-projection-difference.png")
    page.close()
    assert not errors, errors


def test_rendered_board_given_by_its_squares(browser, service, shots, tmp_path):  # noqa: F811
    photos = whole_board_photos(tmp_path / "rendered", n=2)
    page = browser.new_page(viewport={"width": 1366, "height": 768})
    page.goto(f"http://127.0.0.1:{service.port}/")
    page.wait_for_selector("#method option[value=zhang]", state="attached")
    set_board(page, 10, 7, 50)     # the squares of a board of 9 x 6 inner corners
    page.select_option("#method", "zhang")
    page.set_input_files("#files", [str(p) for p in photos])
    page.click("#submit")
    page.wait_for_selector("#board-suggestion", timeout=240_000)
    assert text(page, "#set-progress-label").startswith("ready")
    assert "Found 9 × 6 inner corners in 2 of 2 photos: use that?" in text(page, "#board-suggestion")
    assert "10 × 7" in text(page, "#board-suggestion")
    page.locator("#set-detail").screenshot(path=shots / "05-rendered-squares-counted.png")
    page.close()

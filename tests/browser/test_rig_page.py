"""The rig panel in real Chromium against `freecal serve`: a stereo pair's corners uploaded as two
sets from the page (synthetic cameras of tests/core/test_rig.py, frames 000-007 in both), ticked in
the panel, named, calibrated together; the summary table is the job's summary, the downloads are
the job's files, the rig's 3D view opens on the rig (a frustum per camera, the board at every frame),
a reload lists the rig again; a refused rig says why in page words and makes no job.
Screenshots go to test-artifacts/rig-page/.
"""
from __future__ import annotations

import json
import urllib.parse

import pytest

from ..service.harness import wait_for
from .conftest import open_page, page_service, screenshots, wait_until

service = page_service("rig-page", FREECAL_VIEWER_PORT="0")
shots = screenshots("rig-page")


def rig_jobs(service) -> list[dict]:
    return service.client.get("/api/jobs", params={"kind": "rig"}).json()["jobs"]


@pytest.mark.slow  # two uploads, their calibrations and the rig with its exports: about 20 s
def test_a_stereo_pair_is_calibrated_from_the_rig_panel(browser, service, shots, stereo_pair_files):
    page, errors = open_page(browser, service, "#rig-method option[value=zhang]")
    # each camera's corners uploaded as the page allows (with a quick calibration of its own)
    for path in stereo_pair_files:
        page.set_input_files("#files", str(path))
        page.select_option("#method", "zhang")
        page.click("#submit")
        page.wait_for_selector(f"#sets button[aria-label='set {path.name}']")
    wait_until(page, "document.querySelectorAll('#rig-cameras tbody tr[data-set]').length === 2", timeout=30_000)
    # the cameras in upload order, named after their sets; none ticked until the user says so
    assert page.eval_on_selector_all("#rig-cameras tbody tr[data-set] input[type=text]",
                                     "xs => xs.map(x => x.value)") == ["left", "right"]
    assert page.locator("#rig-cameras input[type=checkbox]:checked").count() == 0
    assert page.text_content("#rig-jobs").strip() == "no rig jobs yet"
    page.get_by_label("left.json", exact=True).check()
    page.get_by_label("right.json", exact=True).check()
    page.fill("#rig-cameras tbody tr:nth-child(2) input[type=text]", "right-cam")   # renamed by the user
    assert page.eval_on_selector_all("#rig-reference option", "os => os.map(o => o.textContent)") == ["left", "right-cam"]
    # the method's settings, as the calibration form has them: each with its help, and only a changed one sent
    page.select_option("#rig-method", "bspline")
    page.click("#rig-settings summary")
    assert page.text_content("#rig-method-help").strip() and page.text_content("#rig-setting-intervals-help").strip()
    page.locator("#rig").screenshot(path=shots / "01-rig-settings.png")
    page.select_option("#rig-method", "zhang")
    assert page.locator("#rig-setting-intervals").count() == 0
    page.fill("#rig-setting-max_iterations", "300")
    page.locator("#rig").screenshot(path=shots / "01-rig-form.png")
    page.click("#rig-submit")

    page.wait_for_selector("#rig-detail:not([hidden])", timeout=10_000)
    assert page.get_attribute("#rig-progress-label", "aria-live") == "polite"
    page.wait_for_selector("#rig-summary", timeout=120_000)
    assert page.is_hidden("#rig-message") and page.is_hidden("#rig-cancel")
    assert page.text_content("#rig-progress-label").startswith("done")
    [job] = rig_jobs(service)
    assert job["rig"]["names"] == ["left", "right-cam"] and job["rig"]["reference"] == "left"
    assert job["method"] == "zhang" and job["rig"]["hold_models"] is False and job["settings"] == {"max_iterations": 300}
    summary = job["summary"]

    # the table is the job's summary: a row per camera, then the rig's
    rows = page.eval_on_selector_all("#rig-summary tbody tr", """rs => rs.map(r => ({
        camera: r.dataset.camera, cells: [...r.querySelectorAll('td')].map(c => c.textContent)}))""")
    assert [r["camera"] for r in rows] == ["left", "right-cam"]
    for row, cam in zip(rows, summary["cameras"], strict=True):
        model, place, rmse, alone, frames = row["cells"]
        assert model == cam["model"] == "zhang" and frames == "8"
        assert place == f"{cam['distance']:.1f} {summary['units']} · {cam['rotation_deg']:.2f}°"
        assert rmse == f"{cam['rmse']:.3f} px" and alone == f"{cam['rmse_alone']:.3f} px"
        assert 0.1 < float(rmse.split()[0]) < 0.4
    assert "(reference)" in page.text_content("#rig-summary tbody tr[data-camera=left] th")
    total = page.eval_on_selector_all("#rig-total td", "cs => cs.map(c => c.textContent)")
    assert total[2] == f"{summary['metrics']['rmse']:.3f} px" and total[4] == "8 used"
    assert "models refined together" in page.text_content("#rig-summary caption")
    page.locator("#rig").screenshot(path=shots / "02-rig-done.png")

    # the downloads are the job's files: rig.json is freecal.rig/1, the exports are there too
    files = page.eval_on_selector_all("#rig-downloads a", "as => as.map(a => a.dataset.file)")
    assert files == ["rig.json", "camchain.yaml", "stereo.yaml"]
    base = f"http://127.0.0.1:{service.port}"
    doc = json.loads(page.request.get(base + page.get_attribute("#rig-downloads a[data-file='rig.json']", "href")).text())
    assert doc["format"] == "freecal.rig/1" and [c["name"] for c in doc["cameras"]] == ["left", "right-cam"]
    for name in ("camchain.yaml", "stereo.yaml"):
        assert page.request.get(base + page.get_attribute(f"#rig-downloads a[data-file='{name}']", "href")).ok

    # the rig's 3D view, embedded: its scene (server side) has a frustum per camera and the board at every frame
    page.click("#rig-open-3d")
    frame = page.wait_for_selector("#rig-viewer3d iframe.viewer-frame")

    def scene():
        clients = service.client.get("/api/viewer").json()["clients"]
        return next((c for c in clients if c["job_id"] == job["id"] and c["nodes"]), None)

    shown = wait_for(scene, 60, "the 3D view to connect and draw the rig", service.logs())
    nodes = set(shown["nodes"])
    assert {"/cameras/0/frustum", "/cameras/1/frustum", "/cameras/0/label", "/cameras/0/z"} <= nodes
    assert {f"/boards/{k}/outline" for k in range(8)} <= nodes and "/field/dx" not in nodes
    assert shown["job_label"].startswith("Rig left + right-cam · zhang · ") and shown["layers"] == {"Boards": True}
    for url in (frame.get_attribute("src"), page.get_attribute("#rig-open-3d-tab", "href")):
        assert f"job={job['id']}" in urllib.parse.unquote(url) and "pair=" not in url, url   # no per-view table to pair
    page.locator("#rig").screenshot(path=shots / "02b-rig-3d.png")
    # a view whose URL names no job may be asked to open on the rig too (POST /api/viewer)
    assert service.client.post("/api/viewer", json={"job_id": job["id"]}).json()["focus"] == job["id"]

    # a reload lists the rig; opening it shows its summary again
    page.reload()
    page.click(f"#rig-jobs button[data-job='{job['id']}']")
    page.wait_for_selector("#rig-summary tbody tr[data-camera='right-cam']", timeout=10_000)
    assert "left + right-cam" in page.text_content("#rig-jobs")
    page.close()
    assert not errors, errors


def test_a_refused_rig_says_why_in_page_words_and_makes_no_job(browser, service, shots, stereo_pair_files):
    ids = []
    for path in stereo_pair_files:   # the sets straight through the API: this test is about the panel's refusal
        r = service.client.post("/api/sets", files={"files": (path.name, path.read_text(), "application/json")})
        assert r.status_code == 201, r.text
        ids.append(r.json()["id"])
    before = len(rig_jobs(service))
    page, errors = open_page(browser, service, "#rig-method option[value=zhang]")
    for set_id in ids:
        page.wait_for_selector(f"#rig-use-{set_id}", timeout=10_000)
        page.check(f"#rig-use-{set_id}")
        page.fill(f"#rig-name-{set_id}", "cam")   # the same name twice
    page.click("#rig-submit")
    page.wait_for_selector("#rig-message:not([hidden])")
    message = page.text_content("#rig-message")
    assert message.startswith("The camera names: 'cam' is given to more than one camera"), message
    page.locator("#rig").screenshot(path=shots / "03-rig-refused.png")

    page.uncheck(f"#rig-use-{ids[1]}")   # one camera only
    page.click("#rig-submit")
    wait_until(page, "document.querySelector('#rig-message').textContent.includes('two or more cameras')", 10_000)
    message = page.text_content("#rig-message")
    assert message.startswith("The cameras' sets: a rig needs two or more cameras"), message
    assert "set_ids" not in message
    assert len(rig_jobs(service)) == before   # nothing was created
    page.close()
    assert not errors, errors

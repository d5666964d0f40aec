"""``freecal report`` as a person opens it: the real command writes the page, Debian's
Chromium (headless, Playwright) opens the file offline, and the page holds what the
results page shows, every figure decoded. Screenshots go to test-artifacts/report/."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from calib_core import calibrate

from ..conftest import ROOT, synthetic

pytestmark = pytest.mark.slow
SHOTS = ROOT / "test-artifacts" / "report"
FIGURE_IDS = ["fig-vectors", "fig-heatmap", "fig-view-errors", "fig-distortion-maps", "fig-distortion-field",
              "fig-knots", "fig-uncertainty", "fig-coverage"]


def test_the_report_opens_offline_with_every_table_and_figure(browser, tmp_path):
    s = synthetic("decentred")
    obs = tmp_path / "train.json"
    s.train.save(obs)
    cal = calibrate(s.train, "bspline", intervals=6)
    cal.save(tmp_path / "cal.json")
    page_file, figures = tmp_path / "out" / "report.html", tmp_path / "out" / "figures"
    run = subprocess.run([sys.executable, "-m", "backend.cli", "report", str(tmp_path / "cal.json"), str(obs),
                          "-o", str(page_file), "--figures", str(figures)],
                         capture_output=True, text=True, timeout=300, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert run.returncode == 0, run.stderr
    assert sorted(p.name for p in figures.iterdir()) == sorted(
        ["coverage.png", "distortion_field.png", "distortion_maps.png", "knot_grid.png", "residual_heatmap.png",
         "residual_vectors.png", "uncertainty.png", "view_errors.png"])

    page = browser.new_page(viewport={"width": 1366, "height": 900})
    fetched: list[str] = []
    page.on("request", lambda r: fetched.append(r.url))
    page.goto(page_file.as_uri())
    assert all(u.startswith(("file:", "data:")) for u in fetched), f"a self-contained page fetches nothing: {fetched}"
    assert page.title() == "cal.json: calibration report"

    params = page.eval_on_selector_all("#parameters-table tbody tr", "rows => rows.map(r => r.innerText)")
    by_name = {row.split("\t")[0]: row.split("\t") for row in params}
    assert {"fx", "fy", "cx", "cy", "skew"} <= set(by_name), params
    assert by_name["fx"][2].startswith("± ") and float(by_name["fx"][2][2:]) > 0
    assert any(name.startswith("B-spline field over") for name in by_name), "the field, summarised"
    views = page.eval_on_selector_all("#views-table tbody tr", "rows => rows.length")
    assert views == len(cal.views)
    shown = page.eval_on_selector_all("figure", "fs => fs.map(f => f.id)")
    assert shown == FIGURE_IDS
    sizes = page.eval_on_selector_all("figure img", "imgs => imgs.map(i => [i.complete, i.naturalWidth])")
    assert all(done and width > 300 for done, width in sizes), sizes  # every PNG decoded

    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=SHOTS / "report-top.png")
    page.screenshot(path=SHOTS / "report-full.png", full_page=True)
    page.close()
    assert (SHOTS / "report-full.png").stat().st_size > 50_000


def test_a_report_from_the_calibration_alone_says_what_it_lacks(browser, tmp_path):
    cal = calibrate(synthetic("radial").train, "zhang")
    cal.save(tmp_path / "cal.json")
    run = subprocess.run([sys.executable, "-m", "backend.cli", "report", str(tmp_path / "cal.json"), "-o",
                          str(tmp_path / "report.html")], capture_output=True, text=True, timeout=300,
                         env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert run.returncode == 0, run.stderr
    page = browser.new_page()
    page.goto((tmp_path / "report.html").as_uri())
    assert "need the observations" in page.inner_text("header")
    assert page.eval_on_selector_all("figure", "fs => fs.map(f => f.id)") == [
        "fig-view-errors", "fig-distortion-maps", "fig-distortion-field"]
    fx = page.eval_on_selector("#parameters-table tbody tr", "r => r.innerText").split("\t")
    assert fx[0] == "fx" and fx[2] == "—"
    page.screenshot(path=SHOTS / "report-calibration-alone.png", full_page=True)
    page.close()

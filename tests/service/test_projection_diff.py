"""GET /api/jobs/{a}/figures/diff/{b}: the page's projection difference between two calibrations,
over real HTTP, equal to `calib_core.evaluation.diff` (what `freecal diff` prints) on the jobs' own files."""
from __future__ import annotations

import numpy as np
import pytest

from calib_core import Calibration
from calib_core.evaluation.diff import projection_diff

from ..conftest import synthetic
from .harness import FAST, Service, create_job, upload_observations, wait_job

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    root = tmp_path_factory.mktemp("diff")
    svc = Service(root / "data", root, FAST).start()
    yield svc
    svc.stop()


@pytest.fixture(scope="module")
def jobs(service):
    """Two calibrations of one synthetic camera (zhang and the rational model) and one of another
    image size."""
    client = service.client
    set_id = upload_observations(client, synthetic("radial").train.to_json())
    ids = [create_job(client, set_id, m) for m in ("zhang", "rational")]
    other = synthetic("radial").train.to_json()
    other["image_size"] = [other["image_size"][0] + 64, other["image_size"][1]]
    ids.append(create_job(client, upload_observations(client, other), "zhang"))
    for job_id in ids:
        assert wait_job(client, job_id, 120, service.logs())["state"] == "done"
    return ids


def calibration(service, job_id: str) -> Calibration:
    return Calibration.from_json(service.client.get(f"/api/jobs/{job_id}/calibration.json").json())


def test_the_page_map_is_freecal_diffs(service, jobs):
    a, b, _ = jobs
    r = service.client.get(f"/api/jobs/{a}/figures/diff/{b}", params={"grid": 40, "fit_region": "covered"})
    assert r.status_code == 200, r.text
    doc = r.json()
    want = projection_diff(calibration(service, a), calibration(service, b), 40, "covered").to_json()
    assert doc["fitted_on"] == want["fitted_on"] == "covered"
    assert doc["grid"] == want["grid"] and len(doc["u"]) == 40
    for region in ("image", "covered"):
        for key in ("median", "p95", "max"):
            assert doc[region][key] == pytest.approx(want[region][key], abs=1e-9)
    mag = np.array(doc["magnitude"], dtype=float)
    np.testing.assert_allclose(mag, np.array(want["magnitude"], dtype=float), atol=1e-6)
    # two fits of one lens agree where their corners were: a fraction of a pixel, not a different camera
    assert doc["covered"]["median"] < 0.5
    # the difference is antisymmetric in its summary: B against A is as far as A against B
    back = service.client.get(f"/api/jobs/{b}/figures/diff/{a}", params={"grid": 40}).json()
    assert back["covered"]["median"] == pytest.approx(doc["covered"]["median"], rel=0.05)


@pytest.mark.parametrize("path, params, status, words", [
    ("{a}/figures/diff/{c}", {}, 422, "different image sizes"),
    ("{a}/figures/diff/nope", {}, 404, "no job with id"),
    ("nope/figures/diff/{a}", {}, 404, "no job with id"),
    ("{a}/figures/diff/{b}", {"grid": 1}, 422, "grid"),
    ("{a}/figures/diff/{b}", {"grid": 100000}, 422, "grid"),
    ("{a}/figures/diff/{b}", {"fit_region": "everywhere"}, 422, "fit_region"),
])
def test_bad_requests_say_what_is_wrong(service, jobs, path, params, status, words):
    a, b, c = jobs
    r = service.client.get("/api/jobs/" + path.format(a=a, b=b, c=c), params=params)
    assert r.status_code == status, r.text
    assert words in r.json()["detail"]


def test_a_job_not_done_cannot_be_compared_yet(service, jobs):
    a = jobs[0]
    set_id = upload_observations(service.client, synthetic("radial").train.to_json())
    running = create_job(service.client, set_id, "bspline")
    r = service.client.get(f"/api/jobs/{a}/figures/diff/{running}")
    if r.status_code == 200:   # it finished first: nothing left to check
        pytest.skip("the job finished before the request")
    assert r.status_code == 409 and "once its calibration is done" in r.json()["detail"]
    wait_job(service.client, running, 120, service.logs())

"""build_scene: one job's objects under their path names, in a real viser server (no browser)."""
from __future__ import annotations

import numpy as np
import pytest

from calib_core import calibrate

from ..conftest import synthetic

QUICK = {"knots": "uniform", "intervals": [4, 4], "max_iterations": 10, "lambda_smooth": 0.1}


@pytest.fixture(scope="module")
def server():
    viser = pytest.importorskip("viser")
    srv = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield srv
    srv.stop()


@pytest.fixture(scope="module")
def result():
    from backend.viewer.data import from_calibration

    obs = synthetic("radial").train
    return from_calibration("job1", calibrate(obs, "bspline", **QUICK), obs)


def test_scene_holds_camera_boards_knots_field_and_vectors(server, result):
    from backend.viewer.scene import build_scene

    built = build_scene(server.scene, result)
    names = set(built.names())
    assert {"/cameras/0/frustum", "/image_plane/outline", "/image_plane/knots", "/residuals/vectors",
            "/field/dx", "/field/dy"} <= names
    assert {f"/boards/{k}/corners" for k in range(len(result.boards))} <= names
    assert len(result.boards) == len(result.calibration.views) > 3
    # each board frame sits at its pose: the median board is 1 scene unit away
    depths = [np.linalg.norm(built.handles[f"/boards/{k}"].position) for k in range(len(result.boards))]
    assert np.median(depths) == pytest.approx(1.0, rel=1e-3)
    assert built.legend["error_max_px"] > 0 and built.legend["field_max_px"] > 0


def test_component_switch_and_rebuild(server, result):
    from backend.viewer.scene import build_scene, set_component

    built = build_scene(server.scene, result, component="Δx")
    assert built.handles["/field/dx"].visible and not built.handles["/field/dy"].visible
    set_component(built, "Δy")
    assert not built.handles["/field/dx"].visible and built.handles["/field/dy"].visible
    again = build_scene(server.scene, result)  # rebuilding replaces, never duplicates
    assert again.names() == built.names()

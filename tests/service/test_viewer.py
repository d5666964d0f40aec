"""build_scene: one job's objects under their path names, in a real viser server (no browser).

What a user reads in the scene: the camera at the origin with labelled axes, each
board in its own colour with its view's name, layers that hide and show, a knot
grid only for a model with a field, surfaces that never cut through a board, and
an opening camera pose that sees the camera and every board.
"""
from __future__ import annotations

import numpy as np
import pytest

from calib_core import calibrate

from ..conftest import synthetic

QUICK = {"knots": "uniform", "intervals": [4, 4], "max_iterations": 10, "lambda_smooth": 0.1}


@pytest.fixture(scope="module")
def obs():
    return synthetic("radial").train


@pytest.fixture(scope="module")
def result(obs):
    from backend.viewer.data import from_calibration

    return from_calibration("job1", calibrate(obs, "bspline", **QUICK), obs)


@pytest.fixture(scope="module")
def fieldless(obs):
    from backend.viewer.data import from_calibration

    return from_calibration("job2", calibrate(obs, "zhang"), obs)


def test_scene_holds_camera_boards_knots_field_and_vectors(server, result):
    from backend.viewer.scene import build_scene

    built = build_scene(server.scene, result)
    names = set(built.names())
    assert {"/cameras/0", "/cameras/0/frustum", "/image_plane/outline", "/image_plane/knots", "/residuals/vectors",
            "/field/dx", "/field/dy"} <= names
    for part in ("plane", "outline", "corners", "label", "highlight"):
        assert {f"/boards/{k}/{part}" for k in range(len(result.boards))} <= names, part
    assert len(result.boards) == len(result.calibration.views) > 3
    # each board frame sits at its pose: the median board is 1 scene unit away
    depths = [np.linalg.norm(built.handles[f"/boards/{k}"].position) for k in range(len(result.boards))]
    assert np.median(depths) == pytest.approx(1.0, rel=1e-3)
    assert built.legend["error_max_px"] > 0 and built.legend["field_max_px"] > 0


def test_camera_axes_and_boards_are_labelled_and_coloured_per_view(server, result):
    from backend.viewer.boards import board_colours
    from backend.viewer.scene import build_scene

    built = build_scene(server.scene, result)
    labels = {p: built.handles[p].text for p in ("/cameras/0/x", "/cameras/0/y", "/cameras/0/z", "/cameras/0/label")}
    assert labels == {"/cameras/0/x": "x right", "/cameras/0/y": "y down", "/cameras/0/z": "z optical axis",
                      "/cameras/0/label": "camera"}
    assert [built.handles[f"/boards/{k}/label"].text for k in range(len(result.boards))] == \
        [b.name for b in result.boards] == built.views
    colours = board_colours(built.handles)
    assert len(colours) == len(result.boards) and len(set(colours.values())) == len(result.boards)
    for k in range(len(result.boards)):   # the sheet wears its view's colour too; the highlight starts hidden
        assert tuple(built.handles[f"/boards/{k}/plane"].color) == colours[f"/boards/{k}"]
        assert not built.handles[f"/boards/{k}/highlight"].visible


def test_field_surfaces_and_image_plane_keep_clear_of_the_boards(server, result):
    from backend.viewer.boards import board_points
    from backend.viewer.scene import build_scene

    built = build_scene(server.scene, result)
    scale = 1.0 / built.legend["scene_unit"]
    boards = np.concatenate([board_points(b, scale) for b in result.boards])
    # the surfaces lie under everything (y is down): their highest vertex below the lowest board corner
    for name in ("dx", "dy"):
        surface = glb_vertices(built.handles[f"/field/{name}"].glb_data)
        assert surface[:, 1].min() > boards[:, 1].max()
    # the image plane (and the vectors and knots on it) is nearer than every board corner
    plane = np.asarray(built.handles["/image_plane/outline"].points).reshape(-1, 3)
    assert plane[:, 2].max() < boards[:, 2].min()
    # the opening camera stands behind the camera (z < 0), above it (y < 0), looking into the rig
    pose = built.view
    assert pose.position[2] < 0 and pose.position[1] < 0 and 0 < pose.look_at[2] < boards[:, 2].max()


def test_a_model_without_a_field_gets_no_knot_grid(server, fieldless):
    from backend.viewer.layers import present
    from backend.viewer.legend import legend
    from backend.viewer.scene import build_scene

    built = build_scene(server.scene, fieldless)
    assert "/image_plane/knots" not in built.handles
    assert present(built.handles) == ["Boards", "Residual vectors", "Field surfaces"]
    assert "no knot grid: this model has no field" in legend(fieldless, built)


def test_layers_and_highlight_change_visibility_without_a_rebuild(server, result):
    from backend.viewer.layers import LAYERS, highlight, present, set_layers
    from backend.viewer.scene import build_scene

    built = build_scene(server.scene, result)
    assert present(built.handles) == list(LAYERS)
    set_layers(built.handles, dict.fromkeys(LAYERS, False))
    assert not any(built.handles[path].visible for path in LAYERS.values())
    set_layers(built.handles, {"Field surfaces": True})
    assert built.handles["/field"].visible and not built.handles["/boards"].visible
    view = result.boards[2].name
    highlight(built.handles, built.views, view)
    shown = [k for k in range(len(result.boards)) if built.handles[f"/boards/{k}/highlight"].visible]
    assert shown == [2]
    highlight(built.handles, built.views, None)
    assert not any(built.handles[f"/boards/{k}/highlight"].visible for k in range(len(result.boards)))


def test_component_switch_and_rebuild(server, result):
    from backend.viewer.scene import build_scene, set_component

    built = build_scene(server.scene, result, component="Δx")
    assert built.handles["/field/dx"].visible and not built.handles["/field/dy"].visible
    set_component(built, "Δy")
    assert not built.handles["/field/dx"].visible and built.handles["/field/dy"].visible
    again = build_scene(server.scene, result)  # rebuilding replaces, never duplicates
    assert again.names() == built.names()


def test_jobs_are_named_as_the_page_names_them():
    import time

    from backend.viewer.names import job_label, unique_labels, when

    now = time.time()
    auto = {"method": "auto", "created_at": now, "summary": {"model": "Kannala-Brandt model (k1..k4)",
                                                             "metrics": {"rmse": 0.2617}}}
    assert job_label(auto, "24 images") == f"24 images · auto → Kannala-Brandt model (k1..k4) · {when(now)} · 0.262 px"
    assert job_label({"method": "compare", "created_at": None, "summary": {"verdict": "zhang"}}, None) == \
        "inline corners · every method compared → zhang"
    assert job_label({"method": "bspline", "created_at": None, "summary": {}}, "s") == "s · method bspline"
    assert when(now - 3 * 86400, now).count(" ") == 2   # another day: "3 May 14:05"
    assert unique_labels([("a", "x"), ("b", "x"), ("c", "y")]) == {"x": "a", "x (2)": "b", "y": "c"}


def glb_vertices(glb: bytes) -> np.ndarray:
    """The vertices of a mesh viser holds as GLB (add_mesh_trimesh)."""
    import io

    import trimesh

    loaded = trimesh.load(io.BytesIO(glb), file_type="glb")
    return np.concatenate([g.vertices for g in loaded.geometry.values()]) if hasattr(loaded, "geometry") \
        else np.asarray(loaded.vertices)

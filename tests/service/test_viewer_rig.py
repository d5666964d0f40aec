"""A rig in the 3D view: a done rig job's cameras and frames, read through the viewer's data path.

The two-camera simulated rig of tests/core/test_rig.py, calibrated with
``calibrate_rig`` and written into a job folder as the worker writes it (rig.json
by ``artefacts.write_rig``, each camera's corners as camera-K.json, the job row
done), is read by ``viewer.data.load`` and drawn by ``rig_scene.build_rig_scene``
in a real viser server: one frustum per camera at the rig's pose, in its own
colour and with its name, the reference marked and carrying the world axes, the
board at every frame; the panel names the job as the page's Rig card does.
"""
from __future__ import annotations

import numpy as np
import pytest

from backend.base.repository import jobs as job_rows
from backend.base.settings import Settings
from calib_core.rig import calibrate_rig

from ..core.test_rig import simulated_rig

NAMES = ["left", "right"]


@pytest.fixture(scope="module")
def cameras():
    sim = simulated_rig([range(0, 6), range(0, 6)], seed=1)
    return dict(zip(NAMES, sim.values(), strict=True))


@pytest.fixture(scope="module")
def rig(cameras):
    return calibrate_rig(cameras, "zhang", reference="right", refine_models=False)


@pytest.fixture(scope="module")
def ctx(tmp_path_factory, cameras, rig):
    """A data directory with the rig as a done job (``job`` below), and one still running."""
    from backend.base.context import Context
    from backend.queue import artefacts

    ctx = Context.open(Settings(data_dir=tmp_path_factory.mktemp("rig-viewer") / "data"))
    spec = {"set_ids": ["s0", "s1"], "names": NAMES, "reference": "right", "hold_models": True}
    for job_id, done in (("0123abcd", True), ("4567cdef", False)):
        out = ctx.storage.job_dir(job_id)
        out.mkdir(parents=True, exist_ok=True)
        for k, name in enumerate(NAMES):
            cameras[name].save(ctx.storage.rig_camera_path(job_id, k))
        job_rows.create(ctx.db, job_id, "rig", None, "zhang", {job_rows.RIG_KEY: spec})
        attempt = job_rows.claim(ctx.db, job_id, "test")
        if done:
            names, unavailable = artefacts.write_rig(out, rig, lambda stage, fraction: None)
            assert job_rows.finish(ctx.db, job_id, attempt, "done", artefacts=names,
                                   summary=artefacts.rig_summary(rig, unavailable))
    return ctx


@pytest.fixture(scope="module")
def result(ctx):
    from backend.viewer import data

    loaded = data.load(ctx, "0123abcd")
    assert isinstance(loaded, data.RigResult)
    return loaded


def test_a_done_rig_job_loads_through_the_data_path_and_others_do_not(ctx, rig, result):
    from backend.viewer import data
    from backend.viewer.names import rig_label

    assert result.rig.to_json() == rig.to_json() and result.method == "zhang"
    # the board at every frame the rig used, posed in the reference camera's frame
    assert [b.name for b in result.boards] == [f"frame {f.frame}" for f in rig.frames]
    for board, frame in zip(result.boards, rig.frames, strict=True):
        assert np.allclose(board.rvec, frame.rvec) and np.allclose(board.tvec, frame.tvec)
        assert np.nanmax(np.abs(board.residuals)) < 2.0   # px: the reference camera's corners, 0.2 px noise
    # a running rig job and an unknown one are not drawn (the panel says to finish a job), as for calibrations
    assert data.load(ctx, "4567cdef") is None and data.load(ctx, "ffff0000") is None
    assert [j["id"] for j in data.done_jobs(ctx)] == ["0123abcd"]
    label = rig_label(data.done_jobs(ctx)[0])
    assert label.startswith("Rig left + right · zhang · ") and label.endswith(f" · {rig.metrics.rmse:.3f} px")


def test_each_camera_is_a_frustum_at_its_pose_in_the_reference_frame(server, rig, result):
    import viser.transforms as tf

    from backend.viewer.rig_scene import build_rig_scene

    built = build_rig_scene(server.scene, result)
    scale = 1.0 / built.legend["scene_unit"]
    for k, cam in enumerate(rig.cameras):
        frame = built.handles[f"/cameras/{k}"]
        assert f"/cameras/{k}/frustum" in built.handles
        # its optical centre, in the board's units, and its axes turned into the reference frame (Rᵀ)
        assert np.allclose(np.asarray(frame.position) / scale, cam.centre, rtol=0, atol=1e-6)
        turned = tf.SO3(np.asarray(frame.wxyz)).as_matrix()
        assert np.allclose(turned, tf.SO3.exp(cam.rvec).as_matrix().T, rtol=0, atol=1e-6)
    reference = [c.name for c in rig.cameras].index("right")
    assert np.allclose(built.handles[f"/cameras/{reference}"].position, 0, atol=1e-12)
    assert np.linalg.norm(rig.camera("left").centre) > 100   # mm: the other camera stands off the origin


def test_cameras_are_named_coloured_and_the_reference_carries_the_world_axes(server, rig, result):
    from backend.viewer.rig_scene import build_rig_scene

    built = build_rig_scene(server.scene, result)
    names = {k: built.handles[f"/cameras/{k}/label"].text for k in range(len(rig.cameras))}
    assert sorted(names.values()) == ["left", "right (reference)"]
    reference = next(k for k, text in names.items() if text.endswith("(reference)"))
    axes = {built.handles[f"/cameras/{reference}/{a}"].text for a in "xyz"}
    assert axes == {"x right", "y down", "z optical axis"} and built.handles[f"/cameras/{reference}"].show_axes
    other = 1 - reference
    assert f"/cameras/{other}/x" not in built.handles and not built.handles[f"/cameras/{other}"].show_axes
    colours = {tuple(built.handles[f"/cameras/{k}/frustum"].color) for k in range(len(rig.cameras))}
    assert len(colours) == len(rig.cameras)
    # a stereo pair stands side by side, turned alike: its names at different heights, not printed over each other
    heights = [-built.handles[f"/cameras/{k}/label"].position[1] for k in range(len(rig.cameras))]
    assert abs(heights[0] - heights[1]) >= 0.5 * built.legend["frustum"]


def test_the_board_is_drawn_at_every_frame_in_its_own_colour(server, rig, result):
    import viser.transforms as tf

    from backend.viewer.boards import board_colours
    from backend.viewer.layers import present
    from backend.viewer.rig_scene import build_rig_scene, rig_legend

    built = build_rig_scene(server.scene, result)
    scale = 1.0 / built.legend["scene_unit"]
    assert built.views == [f"frame {f.frame}" for f in rig.frames]
    for k, frame in enumerate(rig.frames):
        for part in ("plane", "outline", "corners", "label"):
            assert f"/boards/{k}/{part}" in built.handles, (k, part)
        assert built.handles[f"/boards/{k}/label"].text == f"frame {frame.frame}"
        assert np.allclose(np.asarray(built.handles[f"/boards/{k}"].position) / scale, frame.tvec, atol=1e-6)
        assert np.allclose(tf.SO3(np.asarray(built.handles[f"/boards/{k}"].wxyz)).log(), frame.rvec, atol=1e-6)
    assert len(set(board_colours(built.handles).values())) == len(rig.frames)
    # a rig has boards and cameras only: the calibration's other layers are absent (greyed in the panel)
    assert present(built.handles) == ["Boards"]
    assert "/field/dx" not in built.handles and "/image_plane/outline" not in built.handles
    text = rig_legend(result, built)
    assert f"**Rig of 2 cameras, {len(rig.frames)} frames**" in text and "(right, at the origin" in text
    # the opening camera sees every camera and board: it stands behind the reference (z < 0), above it (y < 0)
    assert built.view.position[2] < 0 and built.view.position[1] < 0

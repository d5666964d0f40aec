"""Rigs (formats.md §4): cameras' poses relative to the reference recovered
from simulated rigs, the same answer as OpenCV's stereoCalibrate on a real
stereo pair, freecal.rig/1 read back and self-consistent, and bad rigs refused
saying why."""
from __future__ import annotations

import copy
import dataclasses
import json

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from backend.cli import main
from calib_core.board import BoardSpec
from calib_core.detection.detect import detect_images
from calib_core.errors import DataError, FormatError, SettingsError
from calib_core.models import camera
from calib_core.models.opencv import OpenCVModel
from calib_core.observations import Observations, View
from calib_core.pipeline import calibrate
from calib_core.provenance import UNKNOWN_UNITS
from calib_core.rig import Rig, calibrate_rig, evaluate_rig, frame_of

from ..conftest import shared_data

BOARD = np.array([[x * 60.0, y * 60.0, 0.0] for y in range(7) for x in range(10)])
BOARD_SPEC = {"type": "chessboard", "cols": 10, "rows": 7, "square_size": 60.0, "units": "mm"}
SIZE = (1280, 960)
TRUE_MODELS = [OpenCVModel([900, 902, 640, 480, 0], [-0.12, 0.05, 0.001, -0.0005, 0.0]),
               OpenCVModel([880, 881, 650, 470, 0], [-0.10, 0.03, -0.001, 0.0008, 0.0]),
               OpenCVModel([920, 918, 630, 490, 0], [-0.15, 0.07, 0.0, 0.0, 0.0])]
# camera i's pose relative to the reference: Pc_i = R · Pc_ref + t (mm)
TRUE_EXTRINSICS = np.array([[0, 0, 0, 0, 0, 0],
                            [0.01, 0.06, 0.02, -150.0, 2.0, 5.0],
                            [-0.02, 0.12, 0.01, -300.0, -4.0, 20.0]])


def frame_poses(n: int, rng) -> np.ndarray:
    """Board poses in the reference camera's frame that every camera sees whole."""
    poses = []
    for _ in range(n):
        rot = Rotation.from_euler("xyz", rng.uniform(-0.5, 0.5, 3)).as_rotvec()
        t = np.array([150.0 - 270.0 + rng.uniform(-150, 150), -180.0 + rng.uniform(-120, 120), rng.uniform(1100, 1500)])
        poses.append(np.concatenate([rot, t]))
    return np.array(poses)


def simulated_rig(frames_seen: list[range], sigma: float = 0.2, seed: int = 0) -> dict[str, Observations]:
    rng = np.random.default_rng(seed)
    poses = frame_poses(max(max(r) for r in frames_seen) + 1, rng)
    cameras = {}
    for c, seen in enumerate(frames_seen):
        views = []
        for f in seen:
            p_ref = camera.rotate(poses[f, :3], BOARD) + poses[f, 3:]
            pc = camera.rotate(TRUE_EXTRINSICS[c, :3], p_ref) + TRUE_EXTRINSICS[c, 3:]
            uv = TRUE_MODELS[c].project(pc) + rng.normal(0, sigma, (len(BOARD), 2))
            inside = np.all((uv > 0) & (uv < np.array(SIZE) - 1), axis=1)
            assert inside.all(), "the simulated rig must see every board whole"
            views.append(View(f"cam{c}_{f:03d}.png", BOARD.copy(), uv, np.arange(len(BOARD))))
        cameras[f"cam{c}"] = Observations(SIZE, views, dict(BOARD_SPEC))
    return cameras


def rotation_error(a: np.ndarray, b: np.ndarray) -> float:
    return float((Rotation.from_rotvec(a) * Rotation.from_rotvec(b).inv()).magnitude())


def test_a_three_camera_rig_is_recovered_through_a_chain_of_shared_frames():
    # cam2 never sees a frame the reference sees: it is placed through cam1
    rig = calibrate_rig(simulated_rig([range(0, 12), range(0, 24), range(12, 24)]), "zhang")
    assert rig.reference == "cam0" and [c.name for c in rig.cameras] == ["cam0", "cam1", "cam2"]
    assert rig.diagnostics["cameras"]["cam2"]["frames_shared_with_reference"] == 0
    for c, cam in enumerate(rig.cameras):
        assert rotation_error(cam.rvec, TRUE_EXTRINSICS[c, :3]) < 6e-3  # radians: what a few px of principal point allow
        assert np.linalg.norm(cam.tvec - TRUE_EXTRINSICS[c, 3:]) < 3.0  # mm, of a 150-300 mm baseline
    assert rig.metrics.rmse_axis == pytest.approx(0.2, rel=0.15)  # the corners' noise
    assert [f.frame for f in rig.frames] == [f"{k:03d}" for k in range(24)]
    assert "warnings" not in rig.diagnostics


@pytest.mark.parametrize("change, words", [
    ({"square_size": 50.0}, "square_size 50.0 against 60.0"),
    ({"cols": 7, "rows": 10}, "cols 7 against 10, rows 10 against 7"),
    ({"units": "cm"}, "units 'cm' against 'mm'"),
])
def test_a_camera_that_saw_another_board_is_refused_before_any_calibration(change, words):
    """Shared frames are moments the cameras saw one board: a camera given another board's corners
    pulled every camera's model (points in cm among mm: a rig rmse of 120 px, fx -540)."""
    cameras = simulated_rig([range(0, 10), range(0, 10)])
    cameras["cam1"].board = {**BOARD_SPEC, **change}
    with pytest.raises(DataError, match="camera 'cam1' saw another board than camera 'cam0'") as err:
        calibrate_rig(cameras, "zhang")
    assert words in str(err.value) and "same board spec" in str(err.value)


def test_views_that_are_not_of_one_moment_are_refused():
    """One camera's frame numbers shifted by one (a dropped image): exit 0 with a rig rmse of
    34 px and the other camera's focal length at 12 698 before."""
    cameras = simulated_rig([range(0, 10), range(0, 11)])
    right = cameras["cam1"]
    cameras["cam1"] = Observations(right.image_size, [View(f"cam1_{k:03d}.png", v.object_points, v.image_points, v.ids)
                                                      for k, v in enumerate(right.views[1:])], right.board)
    with pytest.raises(DataError, match=r"cameras 'cam1' and 'cam0': .* differs by \d+° .* not of one moment"):
        calibrate_rig(cameras, "zhang")


def test_frames_numbered_without_the_same_padding_are_named_as_the_reason():
    cameras = simulated_rig([range(0, 8), range(0, 8)])
    for k, view in enumerate(cameras["cam1"].views):
        view.name = f"right{k}.png"  # frame '3' where cam0 has '003'
    with pytest.raises(DataError, match="share no frame") as err:
        calibrate_rig(cameras, "zhang")
    assert "'7' and '007' are different frames" in str(err.value)


def test_a_camera_placed_from_few_shared_frames_is_named_in_a_warning():
    rig = calibrate_rig(simulated_rig([range(0, 10), range(9, 19)]), "zhang")
    assert rig.diagnostics["warnings"] == [
        "camera 'cam1' was placed on the rig from 1 frame shared with camera 'cam0': its pose rests on that alone; "
        "photograph the board with both at 3 or more moments"]


def test_refining_the_models_with_the_rig_predicts_held_out_frames_better():
    # 10 training frames per camera; the hold-out: 20 other frames, noise-free
    train = simulated_rig([range(0, 10)] * 3, seed=0)
    test = simulated_rig([range(10, 30)] * 3, seed=0, sigma=0.0)
    held = evaluate_rig(calibrate_rig(train, "zhang", refine_models=False), test)
    joint = evaluate_rig(calibrate_rig(train, "zhang"), test)
    assert joint["n_shared_frames"] == 20 and set(joint["cameras"]) == {"cam0", "cam1", "cam2"}
    assert joint["rmse"] < 0.8 * held["rmse"]  # measured 0.028 against 0.047 px
    with pytest.raises(DataError, match=r"\['cam9'\] are not in the rig"):
        evaluate_rig(calibrate_rig(train, "zhang"), {"cam9": test["cam0"], "cam1": test["cam1"]})


def test_rig_file_reads_back_and_each_calibration_stands_alone(tmp_path):
    cameras = simulated_rig([range(0, 10), range(0, 10)], seed=1)
    rig = calibrate_rig(cameras, "zhang", reference="cam1")
    assert rig.reference == "cam1" and np.all(rig.camera("cam1").pose == 0)
    path = tmp_path / "rig.json"
    rig.save(path)
    doc = json.loads(path.read_text())
    assert doc["format"] == "freecal.rig/1" and doc["reference"] == "cam1"
    assert set(doc["metrics"]) >= {"rmse", "rmse_axis", "n_points"}
    back = Rig.load(path)
    assert back.to_json() == rig.to_json()
    # a reader of the camera's calibration alone (section 2) projects each view as the rig does
    for cam in back.cameras:
        for view in cam.calibration.views:
            frame = next(f for f in back.frames if f.frame == frame_of(View(view.name, BOARD, BOARD[:, :2])))
            alone = cam.calibration.project(BOARD, view.rvec, view.tvec)
            assert np.allclose(alone, back.project(cam.name, BOARD, frame.rvec, frame.tvec), atol=1e-9)


def test_stereo_pair_agrees_with_opencv_stereo_calibrate():
    folder = shared_data("opencv-stereo-9x6")
    board = BoardSpec.parse("chessboard:9x6:1")
    cameras = {side: detect_images(sorted(folder.glob(f"{side}*.jpg")), board).observations
               for side in ("left", "right")}
    rig = calibrate_rig(cameras, "zhang", outlier_sigma=0, refine_models=False)
    left, right = rig.camera("left").calibration, rig.camera("right").calibration
    obj, img_l, img_r = [], [], []
    by_frame = {side: {frame_of(v): v for v in cameras[side].views} for side in cameras}
    for frame in sorted(set(by_frame["left"]) & set(by_frame["right"])):
        a, b = by_frame["left"][frame], by_frame["right"][frame]
        ids = np.intersect1d(a.ids, b.ids)
        obj.append(a.object_points[np.searchsorted(a.ids, ids)].astype(np.float32))
        img_l.append(a.image_points[np.searchsorted(a.ids, ids)].astype(np.float32))
        img_r.append(b.image_points[np.searchsorted(b.ids, ids)].astype(np.float32))

    def k(cal):
        fx, fy, cx, cy, s = cal.model.intrinsics
        return np.array([[fx, s, cx], [0, fy, cy], [0, 0, 1.0]])

    rms, *_, r, t, _, _ = cv2.stereoCalibrate(obj, img_l, img_r, k(left), left.model.coefficients, k(right),
                                              right.model.coefficients, (640, 480), flags=cv2.CALIB_FIX_INTRINSIC)
    cam = rig.camera("right")
    assert rotation_error(cam.rvec, cv2.Rodrigues(r)[0].ravel()) < 1e-5
    assert np.allclose(cam.tvec, t.ravel(), atol=1e-4)  # squares of 1 unit; baseline 3.3
    assert rig.metrics.rmse == pytest.approx(rms, rel=1e-4)
    joint = calibrate_rig(cameras, "zhang", outlier_sigma=0)  # the models refined with the rig
    assert joint.metrics.rmse < rig.metrics.rmse
    assert joint.diagnostics["solver"]["models_refined"] and not rig.diagnostics["solver"]["models_refined"]


def test_frames_come_from_the_view_field_before_the_name():
    assert frame_of(View("left07.jpg", BOARD, BOARD[:, :2])) == "07"
    assert frame_of(View("img_3_left.png", BOARD, BOARD[:, :2], frame="t=0.25")) == "t=0.25"
    with pytest.raises(DataError, match="names no frame"):
        frame_of(View("left.jpg", BOARD, BOARD[:, :2]))
    doc = simulated_rig([range(0, 3)])["cam0"].to_json()
    doc["views"][0]["frame"] = "first"
    assert Observations.from_json(doc).views[0].frame == "first"
    assert Observations.from_json(json.loads(json.dumps(Observations.from_json(doc).to_json()))).views[0].frame == "first"
    doc["views"][0]["frame"] = 7
    with pytest.raises(FormatError, match="frame"):
        Observations.from_json(doc)


def test_bad_rigs_are_refused_saying_why():
    cameras = simulated_rig([range(0, 6), range(6, 12)])
    steps = []
    with pytest.raises(DataError, match=r"\['cam1'\] share no frame"):
        calibrate_rig(cameras, "zhang", progress=lambda stage, fraction: steps.append(stage))
    assert steps == [], "unshared frames are refused before any camera is calibrated"
    twice = simulated_rig([range(0, 6), range(0, 6)])
    twice["cam1"].views[1].frame = "000"
    with pytest.raises(DataError, match="are both frame '000'"):
        calibrate_rig(twice, "zhang")
    few = simulated_rig([range(0, 6), range(0, 2)])
    with pytest.raises(DataError, match="camera 'cam1': "):
        calibrate_rig(few, "zhang")
    with pytest.raises(DataError, match="at least two cameras"):
        calibrate_rig({"cam0": cameras["cam0"]})
    with pytest.raises(DataError, match="reference camera 'nope'"):
        calibrate_rig(cameras, reference="nope")


def test_a_camera_that_moved_on_the_rig_is_named_in_a_warning():
    """Half its frames shifted by 3 px (the camera turned by a fifth of a degree): each frame
    alone is consistent, and under MAX_FRAME_SCATTER_DEG, but no one pose fits them all."""
    cameras = simulated_rig([range(0, 12), range(0, 12)], seed=2)
    for view in cameras["cam1"].views[6:]:
        view.image_points = view.image_points + [3.0, 0.0]
    rig = calibrate_rig(cameras, "zhang")
    assert [w for w in rig.diagnostics["warnings"] if "'cam1'" in w and "simultaneous" in w]


def test_cli_writes_the_rig_and_refuses_bad_flags(tmp_path, capsys):
    cameras = simulated_rig([range(0, 8), range(0, 8)], seed=3)
    paths = []
    for name, obs in cameras.items():
        obs.save(tmp_path / f"{name}.json")
        paths.append(str(tmp_path / f"{name}.json"))
    out = tmp_path / "rig.json"
    assert main(["rig", *paths, "--method", "zhang", "--names", "left,right", "-o", str(out), "-q"]) == 0
    printed = capsys.readouterr().out
    assert "rmse in rig" in printed and "wrote" in printed
    rig = Rig.load(out)
    assert [c.name for c in rig.cameras] == ["left", "right"]
    assert main(["rig", *paths, "--method", "zhang", "--holdout", *paths, "-q"]) == 0
    assert "hold-out:" in capsys.readouterr().out
    assert main(["rig", *paths, "--holdout", paths[0], "-q"]) == 2
    assert "--holdout: expected 2 files" in capsys.readouterr().err
    small = Observations((640, 480), cameras["cam1"].views, cameras["cam1"].board)
    small.save(tmp_path / "small.json")
    assert main(["rig", *paths, "--holdout", paths[0], str(tmp_path / "small.json"), "-q"]) == 2
    err = capsys.readouterr()
    assert "its images are 640x480, those of camera 'cam1' 1280x960" in err.err and not err.out  # before calibrating
    assert main(["rig", *paths, "--names", "left", "-q"]) == 2
    assert "expected 2 distinct names" in capsys.readouterr().err
    assert main(["rig", paths[0], "-q"]) == 2
    assert "two or more cameras" in capsys.readouterr().err
    assert main(["rig", *paths, "--reference", "middle", "-q"]) == 2
    assert "not one of the cameras" in capsys.readouterr().err


@pytest.mark.slow  # six lean-model fits for Kalibr: 6-13 s
def test_rig_exports_read_by_opencv_and_kalibr_readers(tmp_path, capsys):
    from calib_core.exports.rig import export_rig

    from .consumers import kalibr_camera, kalibr_project

    cameras_of_pair = simulated_rig([range(0, 10)] * 3, seed=4)
    rig = calibrate_rig(cameras_of_pair, "zhang")
    frame = rig.frames[0]
    board_in_ref = camera.rotate(frame.rvec, BOARD) + frame.tvec
    # Kalibr: every camera, each placed from the one before, in metres (the rig's board is in mm);
    # a board projects as the rig projects it
    kalibr = export_rig(rig, "kalibr")
    chain = kalibr.text
    pose = np.eye(4)
    for k, cam in enumerate(rig.cameras):
        entry = kalibr_camera(chain, k)
        if k:
            pose = np.array(entry["T_cn_cnm1"]) @ pose
        pc = 1e-3 * board_in_ref @ pose[:3, :3].T + pose[:3, 3]
        fit = kalibr.cameras[k].fit
        assert np.max(np.abs(kalibr_project(entry, pc) - rig.project(cam.name, board_in_ref))) < 3 * fit.covered.max + 1e-6
    assert np.linalg.norm(np.array(kalibr_camera(chain, 1)["T_cn_cnm1"])[:3, 3]) == pytest.approx(0.150, abs=0.005)
    unitless = copy.deepcopy(rig)  # corners with no board: lengths in units nobody recorded
    unitless.cameras[0].calibration.provenance["tvec_units"] = UNKNOWN_UNITS
    with pytest.raises(SettingsError, match="in metres"):
        export_rig(unitless, "kalibr")
    # OpenCV's stereo file: cv2 reads M1 D1 M2 D2 R T; projectPoints agrees exactly (the models are OpenCV's own)
    with pytest.raises(SettingsError, match="two cameras"):
        export_rig(rig, "opencv")
    pair = Rig(rig.reference, rig.cameras[:2], rig.frames, rig.metrics, rig.diagnostics)
    path = tmp_path / "stereo.yaml"
    path.write_text(export_rig(pair, "opencv").text)
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    m = {key: fs.getNode(key).mat() for key in ("M1", "D1", "M2", "D2", "R", "T")}
    size = (int(fs.getNode("image_width_1").real()), int(fs.getNode("image_height_1").real()))
    r1 = cv2.Rodrigues(np.asarray(frame.rvec))[0]
    uv, _ = cv2.projectPoints(BOARD, cv2.Rodrigues(m["R"] @ r1)[0], m["R"] @ frame.tvec.reshape(3, 1) + m["T"], m["M2"], m["D2"])
    assert np.max(np.abs(uv.reshape(-1, 2) - pair.project("cam1", BOARD, frame.rvec, frame.tvec))) < 1e-6
    assert cv2.stereoRectify(m["M1"], m["D1"], m["M2"], m["D2"], size, m["R"], m["T"])[0].shape == (3, 3)
    assert fs.getNode("T_units").string() == "mm"
    # a pair of a fisheye and an OpenCV camera: neither cv2.stereoRectify nor cv2.fisheye.stereoRectify takes it,
    # so both are written as one model (here OpenCV's: the fisheye camera's lens is OpenCV's own)
    cam1 = pair.cameras[1]
    kb = calibrate(Observations(SIZE, cameras_of_pair["cam1"].views, dict(BOARD_SPEC)), "fisheye")
    mixed = Rig(pair.reference, [pair.cameras[0], dataclasses.replace(cam1, calibration=kb)], pair.frames, pair.metrics,
                pair.diagnostics)
    done = export_rig(mixed, "opencv")
    assert [e.fit.name for e in done.cameras] == ["opencv5", "opencv8"] and not done.cameras[1].fit.exact
    # the command: a rig file goes through freecal export too
    rig_path = tmp_path / "rig.json"
    rig.save(rig_path)
    assert main(["export", str(rig_path), "--to", "opencv", "-o", str(tmp_path / "stereo.yaml")]) == 2
    assert "this rig has 3" in capsys.readouterr().err
    pair.save(rig_path)
    assert main(["export", str(rig_path), "--to", "opencv", "-o", str(tmp_path / "stereo.yaml")]) == 0
    assert "cam1: opencv / opencv (opencv5): exact" in capsys.readouterr().out
    assert main(["export", str(rig_path), "--to", "ros", "-o", str(tmp_path / "x.yaml")]) == 2
    assert "a rig exports to kalibr or opencv" in capsys.readouterr().err

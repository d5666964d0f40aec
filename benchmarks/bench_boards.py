"""Boards nobody chose: detection of random boards, poses and lighting through the synthetic lenses.

python -m benchmarks boards [--trials N] [--first SEED] [--workers N]

Trial ``s`` draws, from its own seed:

- a lens, one of the six synthetic kinds (``synth.ALL_KINDS``);
- a board: a chessboard of 3-13 x 3-10 inner corners (45 %), a ChArUco board of 3-10 x 3-9
  squares in one of eight dictionaries, a fifth of them in OpenCV's legacy layout (40 %), or
  Kalibr's AprilGrid of 3-7 x 3-7 tags (15 %);
- a pose: turned up to 45 deg about the camera's x and y and 27 deg about its axis, filling
  25-90 % of the frame's width, off centre (wide lenses: further off);
- light: a gain of 0.35-1.1, a linear gradient of up to +-20 % across the frame, an offset up
  to 40 grey levels, blur sigma 0.5-1.8 px and noise sigma 0.5-5 grey levels;

renders the view (``synth.render_target``) and detects it (``detect_gray``). Counted per
lens and board type: the corners a detector can be asked for (``bench_detect.refinable``:
the refinement window inside the frame and the image circle, holding no other corner), those
found within 1 px of the truth of their id, and "wrong": corners found more than 2 px from
it. A plain chessboard's ids are compared up to a motion of its lattice (a turn, a mirror, a
shift: a partial chessboard cannot say where on the board it is, and any consistent
labelling is a pose of the board, which calibrates the same).
"""
from __future__ import annotations

import argparse
import os
from concurrent.futures import ProcessPoolExecutor

import cv2
import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from calib_core import synth
from calib_core.board import BoardSpec
from calib_core.detection.corner_error import best_motion
from calib_core.detection.detect_image import detect_gray
from calib_core.errors import SettingsError
from calib_core.synth import render_target

from .bench_detect import _print_table, refinable

DICTIONARIES = ("DICT_4X4_50", "DICT_4X4_250", "DICT_5X5_100", "DICT_6X6_250", "DICT_7X7_1000",
                "DICT_ARUCO_ORIGINAL", "DICT_APRILTAG_36h11", "DICT_APRILTAG_16h5")
FOUND_PX, WRONG_PX = 1.0, 2.0


def random_board(rng: np.random.Generator) -> BoardSpec:
    kind = rng.choice(["chessboard", "charuco", "aprilgrid"], p=[0.45, 0.4, 0.15])
    if kind == "chessboard":
        return BoardSpec.parse(f"chessboard:{rng.integers(3, 14)}x{rng.integers(3, 11)}:{rng.uniform(15, 40):.1f}mm")
    while kind == "charuco":
        square = int(rng.integers(15, 41))   # whole mm, markers a twentieth of a square: the texture draws them exactly
        legacy = ":legacy" if rng.random() < 0.2 else ""
        try:
            return BoardSpec.parse(f"charuco:{rng.integers(3, 11)}x{rng.integers(3, 10)}:{square}mm:"
                                   f"{square * rng.integers(12, 17) / 20:g}mm:{rng.choice(DICTIONARIES)}{legacy}")
        except SettingsError:  # more markers than the dictionary holds: drawn again
            continue
    return BoardSpec.parse(f"aprilgrid:{rng.integers(3, 8)}x{rng.integers(3, 8)}:{rng.uniform(20, 40):.1f}mm:"
                           f"{rng.uniform(0.2, 0.4):.2f}")


def lattice(spec: BoardSpec) -> tuple[int, int]:
    """(cols, rows) of the board's corner ids, row-major."""
    if spec.type == "charuco":
        return spec.cols - 1, spec.rows - 1
    if spec.type == "aprilgrid":
        return 2 * spec.cols, 2 * spec.rows
    return spec.cols, spec.rows


def trial(seed: int) -> dict:
    rng = np.random.default_rng(seed)
    kind = synth.ALL_KINDS[rng.integers(len(synth.ALL_KINDS))]
    spec = random_board(rng)
    pts = spec.object_points(np.arange(spec.n_corners))
    wide = kind in synth.WIDE_KINDS or kind == "fisheye"
    facing = Rotation.from_rotvec([np.pi, 0, 0]) if spec.type == "aprilgrid" else Rotation.identity()  # Kalibr's faces +z
    turn = Rotation.from_rotvec(np.radians(rng.uniform(-45, 45, 3)) * [1, 1, 0.6]) * facing
    fx = synth.INTRINSICS[0]
    width = synth.IMAGE_SIZE[0]
    distance = np.ptp(pts[:, :2], axis=0).max() * fx / (rng.uniform(0.25, 0.9) * width) * (0.7 if wide else 1.0)
    shift = np.array([*rng.uniform(-0.6, 0.6, 2) * distance * (1.3 if wide else 0.9), distance])
    pose = np.concatenate([turn.as_rotvec(), shift - turn.apply(pts.mean(axis=0))])
    img = render_target.render_boards(kind, [(spec, pose)], rng, blur=rng.uniform(0.5, 1.8),
                                      noise=rng.uniform(0.5, 5.0)).astype(np.float32)
    h, w = img.shape
    yy, xx = np.mgrid[0:h, 0:w]
    light = rng.uniform(0.35, 1.1) * (1 + rng.uniform(-0.4, 0.4) * (xx / w - 0.5) + rng.uniform(-0.4, 0.4) * (yy / h - 0.5))
    img = np.clip(np.rint(img * light + rng.uniform(0, 40)), 0, 255).astype(np.uint8)

    pc = turn.apply(pts) + pose[3:]
    truth = np.full((len(pts), 2), np.nan)
    seen = synth.in_view(kind, pc)
    truth[seen] = synth.true_project(kind, pc[seen])
    asked = refinable(kind, truth, *lattice(spec))
    res = detect_gray(img, spec)
    row = {"kind": kind, "type": spec.type, "spec": spec.to_spec(), "asked": int(asked.sum()),
           "used": res.status == "used", "found": 0, "wrong": 0, "errors": [], "reason": res.reason}
    if res.status != "used" or res.ids is None or res.points is None:
        return row
    ids = res.ids if spec.type != "chessboard" else _as_truth(res.ids, res.points, truth, spec.cols, spec.rows)
    e = np.full(len(ids), np.inf)
    e[ids >= 0] = np.linalg.norm(res.points[ids >= 0] - truth[ids[ids >= 0]], axis=1)
    e = np.nan_to_num(e, nan=np.inf)
    good = e < FOUND_PX
    row.update(found=int(np.sum(good & asked[np.maximum(ids, 0)])), wrong=int(np.sum(e > WRONG_PX)),
               errors=e[good].tolist())
    return row


def _as_truth(ids: np.ndarray, points: np.ndarray, truth: np.ndarray, cols: int, rows: int) -> np.ndarray:
    """A chessboard's detected ids mapped through the lattice motion that puts most of them on
    the true corner nearest them (-1: off the board)."""
    near, nearest = cKDTree(np.nan_to_num(truth, nan=1e9)).query(points)
    ours = np.stack([ids % cols, ids // cols], axis=1)
    motion = best_motion(ours[near < WRONG_PX], np.stack([nearest % cols, nearest // cols], axis=1)[near < WRONG_PX])
    if motion is None:
        return np.full(len(ids), -1)
    q = ours @ motion[0].T + motion[1]
    on = (q[:, 0] >= 0) & (q[:, 0] < cols) & (q[:, 1] >= 0) & (q[:, 1] < rows)
    return np.where(on, q[:, 1] * cols + q[:, 0], -1).astype(np.int64)


def _rows(results: list[dict], key: str) -> list[tuple]:
    out = []
    for name in sorted({r[key] for r in results}) + ["all"]:
        rs = [r for r in results if name in ("all", r[key])]
        asked, found = sum(r["asked"] for r in rs), sum(r["found"] for r in rs)
        e = np.array([x for r in rs for x in r["errors"]])
        out.append((name, len(rs), sum(r["used"] for r in rs), asked, found, f"{found / max(asked, 1):.1%}",
                    sum(r["wrong"] for r in rs), f"{np.median(e):.3f}" if e.size else "—",
                    f"{e.max():.2f}" if e.size else "—"))
    return out


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks boards", description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=150, help="the table in docs/detection.md is of 150")
    ap.add_argument("--first", type=int, default=0, help="the first trial's seed")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    a = ap.parse_args(argv)
    cv2.setNumThreads(1)
    seeds = range(a.first, a.first + a.trials)
    with ProcessPoolExecutor(a.workers) as pool:
        results = list(pool.map(trial, seeds, chunksize=4))
    header = ["", "trials", "boards used", "corners asked", "found", "share", "wrong", "median px", "max px"]
    print(f"## Random boards, trials {a.first}-{a.first + a.trials - 1}\n")
    print(f"Found: within {FOUND_PX:g} px of the truth of its id; wrong: beyond {WRONG_PX:g} px.\n")
    for key in ("type", "kind"):
        print(f"By {'board type' if key == 'type' else 'lens'}:\n")
        _print_table(header, _rows(results, key))
        print()
    print("Boards not used, and why:\n")
    for r in results:
        if not r["used"]:
            print(f"- {r['spec']} through {r['kind']}: {r['asked']} corners asked; {r['reason']}")
    print()
    return 0

"""Calibrate with mrcal, for the side-by-side benchmark (``mrcal_bridge.py``).

Runs under mrcal's own interpreter (``mrcal_bridge.interpreter()``, Python ≥ 3.12:
mrcal has no wheel for the project's 3.11), so it imports nothing from
freecal.  Usage: ``python mrcal_fit.py IN.npz OUT.npz``.

IN holds the corners on mrcal's full-grid layout: ``train`` and ``test``
(views, H, W, 3) of (x, y, weight), missing corners at weight −1,
``imagersize`` (W, H), ``train_spacing``, ``test_spacing`` (each set its own
grid).  We follow ``mrcal-calibrate-cameras``: a stereographic seed
(``mrcal.seed_stereographic``), a geometry-only solve, a core solve, then the
full model with mrcal's default regularisation and outlier rejection (a
splined model's core locked, as mrcal does): OPENCV8, then
SPLINED_STEREOGRAPHIC from OPENCV8's poses, and the splined model straight
from the seed (``fit_all``).  Not done, to keep both methods on the same model
of the board: the board-warp solve (freecal assumes a flat board; the
synthetic boards are flat).

Each fixed model is then evaluated on ``test`` with a pose-only refit
(``mrcal.optimize`` with the intrinsics locked, every corner kept), freecal's
hold-out protocol (``calib_core.evaluation.evaluate``).  OUT holds ``error`` if no seed
worked, else per model ``m``: ``m_lensmodel``, ``m_intrinsics``,
``m_seconds`` (CPU time of this process, the stages it builds on included:
the benchmark machine may be shared), residuals ``m_train`` / ``m_test``
(views, H, W, 2) and the masks ``m_train_used`` (observed and not rejected) /
``m_test_used``; the caller computes the rmse from those, per corner actually
observed (mrcal's own printed rms counts the missing ones as zeros).
"""
import sys
import threading
import time

import mrcal
import numpy as np

STACK_BYTES = 512 << 20  # mrcal.optimize overflows the default 8 MiB stack on ~50k-corner problems
# Knots across (Ny follows the image's angular aspect).  On the synthetic hold-out
# 16 is mrcal's best overall of 10 / 16 / 24: 10 underfits the radial lens (0.94 px),
# 24 overfits ~2000 corners (0.24-1.5 px).
SPLINE_NX = 16
SPLINE_ORDER = 3
# mrcal needs a focal guess (freecal's init does not).  Its seed's PnP fails for some
# guesses (asymmetric lens: 0.3…0.5 × width; fisheye: 0.25), so, as a user would, we
# retry with the next guess; every try is counted in the time.
FOCAL_GUESSES = (0.5, 1.0, 0.25)  # × image width


def optimize(**kw) -> dict:
    """mrcal.optimize in a thread with a large stack (big boards)."""
    out = {}

    def run():
        try:
            out["stats"] = mrcal.optimize(**kw)
        except Exception as exc:  # re-raised in the caller's thread
            out["error"] = exc

    old = threading.stack_size(STACK_BYTES)
    try:
        t = threading.Thread(target=run)
        t.start()
        t.join()
    finally:
        threading.stack_size(old)
    if "error" in out:
        raise out["error"]
    return out["stats"]


def problem(obs, intrinsics, rt_ref_frame, lensmodel, imagersize, spacing, **flags) -> dict:
    """mrcal.optimize's arguments for one camera at the reference frame."""
    n = len(obs)
    idx = np.stack([np.arange(n), np.zeros(n), -np.ones(n)], axis=-1).astype(np.int32)
    kw = dict(intrinsics=intrinsics, rt_cam_ref=np.zeros((0, 6)), rt_ref_frame=rt_ref_frame, points=None,
              observations_board=obs, indices_frame_camintrinsics_camextrinsics=idx,
              observations_point=None, indices_point_camintrinsics_camextrinsics=None,
              lensmodel=lensmodel, imagersizes=np.array([imagersize], dtype=np.int32), calobject_warp=None,
              do_optimize_intrinsics_core=True, do_optimize_intrinsics_distortions=True,
              do_optimize_extrinsics=False, do_optimize_frames=True, do_optimize_calobject_warp=False,
              calibration_object_spacing=spacing, do_apply_outlier_rejection=True,
              do_apply_regularization=True, verbose=False)
    kw.update(flags)
    return kw


def seed(obs, imagersize, spacing, focal):
    """mrcal-calibrate-cameras' seed: stereographic intrinsics and board poses,
    then geometry only, then the stereographic core.  Returns (intrinsics, rt_ref_frame)."""
    n = len(obs)
    ifc = np.stack([np.arange(n), np.zeros(n)], axis=-1).astype(np.int32)
    intr, _, rt = mrcal.seed_stereographic(imagersizes=[imagersize], focal_estimate=focal,
                                           indices_frame_camera=ifc, observations=obs, object_spacing=spacing)
    common = dict(do_optimize_calobject_warp=False, do_apply_outlier_rejection=False, do_apply_regularization=False)
    optimize(**problem(obs, intr, rt, "LENSMODEL_STEREOGRAPHIC", imagersize, spacing,
                       do_optimize_intrinsics_core=False, do_optimize_intrinsics_distortions=False, **common))
    optimize(**problem(obs, intr, rt, "LENSMODEL_STEREOGRAPHIC", imagersize, spacing,
                       do_optimize_intrinsics_distortions=False, **common))
    return intr, rt


def first_seed(obs, imagersize, spacing):
    """The seed of the first focal guess whose PnP works (``FOCAL_GUESSES``)."""
    errors = []
    for f in FOCAL_GUESSES:
        try:
            return seed(obs, imagersize, spacing, f * imagersize[0])
        except Exception as exc:  # e.g. "solvePnP() insists that tvec.z <= 0"
            errors.append(f"focal {f} × width: {exc}")
    raise RuntimeError("no focal guess gave a usable mrcal seed: " + "; ".join(errors))


def splined_model(intr, rt, obs, imagersize, spacing) -> str:
    """The splined model's name: its domain wide enough for the image's edge
    midpoints (through the stereographic core ``intr``) and for every observed
    corner's ray (through the board poses ``rt``, the seed's or OPENCV8's: the core
    alone misplaces them where the lens departs from stereographic), 5 % margin;
    knots square in u, as mrcal's are."""
    fxy, cxy = intr[0, :2], intr[0, 2:4]
    w, h = imagersize
    edges = np.array([[0, (h - 1) / 2], [w - 1, (h - 1) / 2], [(w - 1) / 2, 0], [(w - 1) / 2, h - 1]])
    board = mrcal.ref_calibration_object(obs.shape[2], obs.shape[1], spacing)
    rays = mrcal.transform_point_rt(rt[:, None, None, :], board[None])[obs[..., 2] > 0]
    u = np.abs(np.vstack([(edges - cxy) / fxy, mrcal.project_stereographic(rays)]))  # normalised: u = 2 tan(θ/2)
    ux, uy = 1.05 * u.max(axis=0)
    fov_x = np.degrees(4 * np.arctan(ux / 2))
    ny = int(np.ceil(SPLINE_NX * uy / ux))
    return f"LENSMODEL_SPLINED_STEREOGRAPHIC_order={SPLINE_ORDER}_Nx={SPLINE_NX}_Ny={ny}_fov_x_deg={fov_x:.0f}"


def expand(intr, lensmodel):
    """Seed intrinsics padded with tiny distortions (mrcal-calibrate-cameras' expand_intrinsics)."""
    n_new = mrcal.lensmodel_num_params(lensmodel) - intr.shape[-1]
    new = np.random.default_rng(0).uniform(-1e-6, 1e-6, (len(intr), n_new))
    if "OPENCV" in lensmodel:
        new[:, 5:8] *= 1e-3  # rational terms near 0: keeps the denominator ≈ 1
    return np.hstack([intr, new])


def residuals(obs, intrinsics, rt_ref_frame, lensmodel, spacing):
    """(views, H, W, 2) projected minus observed, and the mask of corners in use."""
    h, w = obs.shape[1:3]
    board = mrcal.ref_calibration_object(w, h, spacing)
    q = mrcal.project(mrcal.transform_point_rt(rt_ref_frame[:, None, None, :], board[None]), lensmodel, intrinsics)
    return q - obs[..., :2], obs[..., 2] > 0


def board_poses(obs, intrinsics, lensmodel, spacing):
    """rt_ref_frame seeds by planar PnP (IPPE) on the model's rays within 75° of the
    axis.  mrcal's own PnP wrapper (pinhole reprojection of the whole board) fails
    on the synthetic hold-out's wide, tilted 80 × 80 boards ("tvec.z <= 0")."""
    import cv2

    h, w = obs.shape[1:3]
    board = mrcal.ref_calibration_object(w, h, spacing)
    rts = []
    for view in obs:
        seen = view[..., 2] > 0
        v = mrcal.unproject(np.ascontiguousarray(view[..., :2][seen]), lensmodel, intrinsics, normalize=True)
        ok = np.isfinite(v).all(axis=1) & (v[:, 2] > np.cos(np.radians(75)))
        found, rvec, tvec = cv2.solvePnP(board[seen][ok], v[ok, :2] / v[ok, 2:], np.eye(3), None,
                                         flags=cv2.SOLVEPNP_IPPE)
        if not found:
            raise RuntimeError("PnP found no pose for a hold-out view")
        rts.append(np.concatenate([rvec.ravel(), tvec.ravel()]))
    return np.array(rts)


def holdout(obs, intrinsics, lensmodel, imagersize, spacing):
    """The fixed model on other views: seed each pose by PnP, refit poses only."""
    rt = board_poses(obs, intrinsics[0], lensmodel, spacing)
    optimize(**problem(obs, intrinsics.copy(), rt, lensmodel, imagersize, spacing,
                       do_optimize_intrinsics_core=False, do_optimize_intrinsics_distortions=False,
                       do_apply_outlier_rejection=False, do_apply_regularization=False))
    return residuals(obs, intrinsics, rt, lensmodel, spacing)


def solve(train, seed_intr, seed_rt, lensmodel, imagersize, spacing):
    """One full-model solve from a seed: (observations with outliers marked, intrinsics, poses)."""
    obs, rt = train.copy(), seed_rt.copy()  # mrcal marks outliers in place (weight < 0)
    intr = expand(seed_intr, lensmodel)
    # mrcal locks a splined model's core: the spline and the core trade off.
    optimize(**problem(obs, intr, rt, lensmodel, imagersize, spacing,
                       do_optimize_intrinsics_core=not lensmodel.startswith("LENSMODEL_SPLINED")))
    return obs, intr, rt


def fit_all(train, imagersize, spacing):
    """{name: (obs, intrinsics, poses, lensmodel, CPU seconds)}: OPENCV8 from the
    stereographic seed; the splined model from OPENCV8's board poses (its rays
    also set the spline's domain), and, as mrcal-calibrate-cameras does it,
    directly from the seed.  Each time counts every stage it builds on."""
    clock = time.process_time  # every thread of the process, mrcal.optimize's included
    out = {}
    t0 = clock()
    intr, rt = first_seed(train, imagersize, spacing)
    t_seed = clock() - t0
    t0 = clock()
    o8 = solve(train, intr, rt, "LENSMODEL_OPENCV8", imagersize, spacing)
    t8 = clock() - t0
    out["opencv8"] = (*o8, "LENSMODEL_OPENCV8", t_seed + t8)
    for name, base_rt, before in (("splined", o8[2], t_seed + t8), ("splined_direct", rt, t_seed)):
        t0 = clock()
        lensmodel = splined_model(intr, base_rt, train, imagersize, spacing)
        out[name] = (*solve(train, intr, base_rt, lensmodel, imagersize, spacing), lensmodel, before + clock() - t0)
    return out


def main(argv) -> int:
    src, dst = argv
    d = np.load(src)
    imagersize = tuple(int(x) for x in d["imagersize"])
    spacing, test_spacing = float(d["train_spacing"]), float(d["test_spacing"])
    try:
        fits = fit_all(d["train"], imagersize, spacing)
    except Exception as exc:  # reported in the table, not hidden
        np.savez(dst, error=f"{type(exc).__name__}: {exc}")
        return 0
    out = {}
    for name, (obs, intr, rt, lensmodel, seconds) in fits.items():
        r_train, used_train = residuals(obs, intr, rt, lensmodel, spacing)
        try:
            r_test, used_test = holdout(d["test"].copy(), intr, lensmodel, imagersize, test_spacing)
        except Exception as exc:
            out[f"{name}_error"] = f"hold-out: {type(exc).__name__}: {exc}"
            continue
        out.update({f"{name}_lensmodel": lensmodel, f"{name}_intrinsics": intr[0], f"{name}_seconds": seconds,
                    f"{name}_train": r_train, f"{name}_train_used": used_train,
                    f"{name}_test": r_test, f"{name}_test_used": used_test})
    np.savez(dst, **out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

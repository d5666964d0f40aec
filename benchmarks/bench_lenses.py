"""The default on lenses outside the paper's protocol: what lens would break it?

python -m benchmarks lenses [--tables lenses,hd,elliptic,cameras,bases,random] [--seeds 0,1,2] [--views 12]
                            [--sigma 0.2] [--wide-seeds 0,1,2,3,4,5] [--stretches 1.15,1.3,1.5] [--random-seeds 0,...,11]

Boards seen through lenses OpenCV itself projects (``calib_core.synth.opencv_lenses``:
a 640 x 480 camera; OpenCV's webcam-like model, a mustache, a thin prism, a tilted
sensor, and the webcam lens with a smooth ripple of 0.15 to 1.2 px that no parametric
model has). For each lens and seed: the default's choice and its error on noise-free
views over the whole image (model held, poses refit), against the best in hindsight of
the models it chooses among, each fitted alone with its own search (zhang, Kannala-Brandt,
rational, the paper's field, a field over the rational core).

``hd``: the same lenses through a 1280 x 720 camera (``opencv_lenses.through``), 10 views,
σ = 0.3 px, boards up to half the distance off centre, many of them partly seen.

``elliptic``: a lens whose distortion is radial in a stretched frame (an anamorphic
element's), the same protocol; the default against the same, and against the default
with the field screen's first question alone (each view's pose held), which turned
every field away on most of these sets.

``cameras``: other cameras, the same protocol at their own sizes: a 4000 px telephoto, a
principal point far off centre, an equisolid and a stereographic fisheye, a pincushion lens
and a nearly distortion-free 1920 x 1080 camera.

``bases``: the paper's model (``--method bspline``) on each base projection, against the
base "auto" takes (``bspline.base_for``), on the lenses above, the synthetic kinds, OpenCV's
fisheye lens seen within 60° and BabelCalib's fisheye (train → test).

``random``: lenses drawn at random (``opencv_lenses.random_lens``: OpenCV's rational model
at four image sizes, with smooth bumps, with a tilted sensor, and OpenCV's fisheye model),
none of them looked at before it was measured.
"""
from __future__ import annotations

import argparse
import functools
import math
import sys
from unittest import mock

import numpy as np

from calib_core.errors import CalibError
from calib_core.evaluation.evaluate import validation_residuals
from calib_core.fitting.metrics import rmse
from calib_core.methods import field_screen
from calib_core.synth import opencv_lenses as lenses

from .bench_default import TARGET_BEST, markdown, timed, verdict

LENSES = {
    "webcam": lenses.webcam_lens,
    "mustache": lenses.mustache_lens,
    "thin prism": lenses.prism_lens,
    "tilted sensor": lenses.tilted_lens,
    **{f"ripple {a:g} px": functools.partial(lenses.rippled_lens, amplitude=a) for a in (0.15, 0.3, 0.6, 1.2)},
}
ALONE = {"zhang": ("zhang", {}), "fisheye": ("fisheye", {}), "rational": ("rational", {}),
         "bspline": ("bspline", {}), "hybrid-rational": ("bspline", {"core": "rational"})}


def holdout_rmse(cal, holdout) -> float:
    return rmse(validation_residuals(cal, holdout)[0])


def best_alone(train, holdout) -> tuple[str, float]:
    """The candidate fitted alone that predicts ``holdout`` best, and its error."""
    alone = {}
    for label, (method, settings) in ALONE.items():
        try:
            alone[label] = holdout_rmse(timed(train, method, **settings)[0], holdout)
        except CalibError:
            continue
    best = min(alone, key=alone.__getitem__)
    return best, alone[best]


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks lenses")
    ap.add_argument("--tables", default="lenses,hd,elliptic,cameras",
                    help="any of lenses, hd, elliptic, cameras, bases, random")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--views", type=int, default=12, help="training views")
    ap.add_argument("--sigma", type=float, default=0.2, help="corner noise [px]")
    ap.add_argument("--stretches", default="1.15,1.3,1.5", help="elliptic: the lens's stretch along x")
    ap.add_argument("--wide-seeds", default="0,1,2,3,4,5", help="hd, elliptic and cameras: seeds")
    ap.add_argument("--random-seeds", default=",".join(map(str, range(12))), help="random: the lenses drawn, per kind")
    a = ap.parse_args(argv)
    sys.stdout.reconfigure(line_buffering=True)
    if "lenses" in a.tables.split(","):
        lens_table(a)
    if "hd" in a.tables.split(","):
        hd_table(a)
    if "elliptic" in a.tables.split(","):
        elliptic_table(a)
    if "cameras" in a.tables.split(","):
        cameras_table(a)
    if "bases" in a.tables.split(","):
        bases_table(a)
    if "random" in a.tables.split(","):
        random_table(a)
    return 0


def lens_table(a) -> None:
    default_table(f"The default on lenses outside the paper's protocol (640 x 480, {a.views} views, σ = {a.sigma} px; "
                  "hold-out: 10 noise-free views, model held, poses refit)",
                  ((name, seed, *lens_views(lens, seed, a.views, a.sigma))
                   for name, lens in LENSES.items() for seed in seeds(a.seeds)))


def seeds(text: str) -> list[int]:
    return [int(x) for x in text.split(",")]


def default_table(title: str, sets) -> None:
    """The default against the best alone on each of ``sets`` (name, seed, training, hold-out), and a summary."""
    print(f"## {title}\n")
    rows, ratios = [], []
    for name, seed, train, holdout in sets:
        row, ratio = default_row(name, seed, train, holdout)
        rows.append(row)
        ratios.append(ratio)
    markdown(DEFAULT_HEADERS, rows)
    summary("default", ratios)


def lens_views(lens, seed: int, views: int = 12, sigma: float = 0.2):
    """(training, hold-out) views of one of LENSES through its 640 x 480 camera: the hold-out
    10 noise-free views."""
    return (lenses.views_of(lens, (640, 480), views, seed=seed, sigma=sigma, distance=450, spread=0.2),
            lenses.views_of(lens, (640, 480), 10, seed=10 + seed, sigma=0.0, distance=450, spread=0.2))


DEFAULT_HEADERS = ["lens", "seed", "default chose", "default hold-out", "CPU s", "best alone (hindsight)",
                   "its hold-out", f"default / best (≤ {TARGET_BEST:g})", "verdict"]


def default_row(name: str, seed: int, train, holdout) -> tuple[list, float]:
    """(table row, default / best alone) of the default on ``train``, scored on ``holdout``."""
    cal, cpu = timed(train, "auto")
    ours = holdout_rmse(cal, holdout)
    best, its = best_alone(train, holdout)
    return ([name, seed, cal.settings["chosen"], ours, f"{cpu:.2f}", best, its, ours / its,
             verdict(ours <= TARGET_BEST * its)], ours / its)


def wide_views(lens, seed: int):
    """(train, holdout): 10 views at σ = 0.3 px and 30 noise-free ones through a 1280 x 720 camera,
    boards up to half the distance off centre."""
    return (lenses.views_of(lens, (1280, 720), 10, seed, 0.3, 600, 0.5),
            lenses.views_of(lens, (1280, 720), 30, seed + 1000, 0.0, 600, 0.5))


def hd_table(a) -> None:
    default_table("The lenses through a 1280 x 720 camera (10 views, σ = 0.3 px, boards up to half the distance off "
                  "centre; hold-out: 30 noise-free views)",
                  ((name, seed, *wide_views(lenses.through(lens), seed))
                   for name, lens in LENSES.items() for seed in seeds(a.wide_seeds)))


def summary(label: str, ratios: list[float]) -> None:
    print(f"{label}: {sum(x <= TARGET_BEST for x in ratios)} of {len(ratios)} within {TARGET_BEST:g} × the best "
          f"alone, {sum(x > 2 for x in ratios)} beyond 2 ×, worst {max(ratios):.2f}, geometric mean "
          f"{math.exp(sum(map(math.log, ratios)) / len(ratios)):.3f}\n")


def elliptic_table(a) -> None:
    print("## Elliptic lenses (1280 x 720, 10 views, σ = 0.3 px, boards up to half the distance off centre; "
          "hold-out: 30 noise-free views)\n")
    rows, ratios = [], {"now": [], "held": []}
    for stretch in (float(x) for x in a.stretches.split(",")):
        lens = functools.partial(lenses.elliptic_lens, stretch=stretch, camera=lenses.HD)
        for seed in seeds(a.wide_seeds):
            train, holdout = wide_views(lens, seed)
            now, cpu = timed(train, "auto")
            with mock.patch.object(field_screen, "POSED_MIN_SHARE", math.inf):  # the poses held: the screen before
                held, cpu_held = timed(train, "auto")
            best, its = best_alone(train, holdout)
            errors = {"now": holdout_rmse(now, holdout), "held": holdout_rmse(held, holdout)}
            for k in ratios:
                ratios[k].append(errors[k] / its)
            rows.append([stretch, seed, now.settings["chosen"], errors["now"], f"{cpu:.2f}", held.settings["chosen"],
                         errors["held"], f"{cpu_held:.2f}", best, its, errors["now"] / its, errors["held"] / its])
    markdown(["stretch", "seed", "default chose", "hold-out", "CPU s", "poses held: chose", "hold-out", "CPU s",
              "best alone", "its hold-out", "default / best", "poses held / best"], rows)
    summary("default", ratios["now"])
    summary("poses held", ratios["held"])


# name → (projection, image size, board distance [mm], spread): OpenCV's model at other cameras
# (``opencv_lenses.through``) and two fisheye projections no model of freecal's has in closed form
CAMERAS = {
    "telephoto 4000 px": (lenses.through(lenses.opencv_lens([0.05, 0, 0, 0, 0]), lenses.camera_matrix(4000, 4000, 640, 512)),
                          (1280, 1024), 2500, 0.08),
    "principal point off centre": (lenses.through(lenses.opencv_lens([-0.25, 0.08, 0, 0, 0]), lenses.camera_matrix(700, 700, 420, 300)),
                                   (1280, 720), 600, 0.4),
    "equisolid fisheye": (lenses.equisolid_lens, (1280, 1024), 300, 0.8),
    "stereographic fisheye": (lenses.stereographic_lens, (1280, 1024), 300, 0.8),
    "pincushion": (lenses.through(lenses.opencv_lens([0.25, 0.1, 0, 0, 0]), lenses.camera_matrix(900, 900, 640, 360)), (1280, 720), 700, 0.4),
    "nearly distortion-free": (lenses.through(lenses.opencv_lens([0.01, 0, 0, 0, 0]), lenses.camera_matrix(1400, 1400, 960, 540)),
                               (1920, 1080), 900, 0.4),
}


def camera_views(name: str, seed: int):
    """(training, hold-out) views of one of CAMERAS: 10 at σ = 0.3 px, 30 noise-free."""
    lens, size, distance, spread = CAMERAS[name]
    return (lenses.views_of(lens, size, 10, seed, 0.3, distance, spread),
            lenses.views_of(lens, size, 30, seed + 1000, 0.0, distance, spread))


def random_views(kind: str, seed: int, views: int = 10):
    """(training, hold-out) views of ``opencv_lenses.random_lens``: ``views`` at σ = 0.3 px, 10 noise-free."""
    lens, size, distance, spread = lenses.random_lens(kind, seed)
    return (lenses.views_of(lens, size, views, seed, 0.3, distance, spread),
            lenses.views_of(lens, size, 10, seed + 1000, 0.0, distance, spread))


def random_table(a) -> None:
    default_table("Lenses drawn at random (opencv_lenses.random_lens; 10 views, σ = 0.3 px; hold-out: 10 noise-free "
                  "views)", ((kind, seed, *random_views(kind, seed))
                             for kind in lenses.RANDOM_KINDS for seed in seeds(a.random_seeds)))


def cameras_table(a) -> None:
    default_table("Other cameras (10 views, σ = 0.3 px; hold-out: 30 noise-free views)",
                  ((name, seed, *camera_views(name, seed)) for name in CAMERAS for seed in seeds(a.wide_seeds)))


def base_sets(seeds: list[int]):
    """(label, train, holdout) of every set the base table scores."""
    from calib_core import synth

    from .bench_compare import load_real

    for kind in ("radial", "asymmetric", "freeform", "decentred", "fisheye", "fisheye200"):
        for seed in seeds:
            s = synth.generate(kind, 0.3, seed)
            yield f"{kind} (synth) {seed}", s.train, s.holdout
    for name in ("webcam", "mustache", "thin prism", "tilted sensor"):
        for seed in seeds:
            yield f"{name} {seed}", *lens_views(LENSES[name], seed)
    for name in CAMERAS:
        for seed in seeds:
            yield f"{name} {seed}", *camera_views(name, seed)
    for seed in seeds:
        yield (f"OpenCV's fisheye lens, within 60° {seed}",
               lenses.views_of(lenses.fisheye_lens, (1280, 1024), 10, seed=seed, sigma=0.3, distance=260, spread=0.5),
               lenses.views_of(lenses.fisheye_lens, (1280, 1024), 10, seed=1000 + seed, sigma=0.0, distance=260,
                               spread=0.5))
    babel = load_real()
    if babel is not None:
        yield "BabelCalib ov_plane (train → test)", *babel


def bases_table(a) -> None:
    """Each set's hold-out with the paper's model on every base, and the base "auto" takes."""
    from calib_core.fitting.init import initialise
    from calib_core.methods.bspline import PINHOLE_MISFIT, base_for
    from calib_core.models.camera import BASES
    from calib_core.pipeline import to_data

    print("## The paper's model on each base projection (--method bspline; hold-out: noise-free views, "
          "model held, poses refit)\n")
    rows, ratios = [], []
    for label, train, holdout in base_sets(seeds(a.seeds)):
        data, _, _ = to_data(train)
        auto, _ = base_for(initialise(data, train.image_size), data)
        errors = {}
        for base in BASES:
            try:
                errors[base] = holdout_rmse(timed(train, "bspline", base=base)[0], holdout)
            except CalibError:
                errors[base] = math.inf
        best = min(errors, key=errors.__getitem__)
        ratios.append(errors[auto] / errors[best])
        rows.append([label, *(f"{errors[b]:.3g}" for b in BASES), best, auto, f"{errors[auto] / errors['pinhole']:.3g}",
                     f"{ratios[-1]:.3g}"])
    markdown(["set", *(f"{b} hold-out" for b in BASES), "best base", "auto takes", "auto / pinhole",
              "auto / best"], rows)
    print(f"auto (pinhole unless the initial camera lies more than {PINHOLE_MISFIT:g} from every pinhole camera "
          f"and nearer another base): the best base on {sum(r <= 1.0 for r in ratios)} of {len(ratios)} sets, "
          f"within 1.1x of it on {sum(r <= 1.1 for r in ratios)}, geometric mean "
          f"{math.exp(float(np.mean(np.log(ratios)))):.3f}.\n")

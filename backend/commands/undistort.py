"""freecal undistort CAL.json [IMAGES...] -o DIR [--alpha A | --keep valid|all|covered | --focal F] [--size WxH] [--maps]"""
from __future__ import annotations

import json
from pathlib import Path

from calib_core.errors import SettingsError
from calib_core.products.rectify import (
    RectifiedCamera,
    RectifyError,
    covered_camera,
    fixed_camera,
    photo_size,
    rectified_camera,
    rectify_image,
    save_maps,
    undistort_maps,
)

from .inputs import load_calibration
from .output import claim_stdout, print_json
from .outputs import Outputs

KEEP = {"valid": 0.0, "all": 1.0}  # and "covered": the corners' region, covered_camera
KEEP_HELP = ("valid: only pixels with a source (default); all: every photo pixel; covered: only the region the "
             "corners covered (where the lens was measured)")
ALPHA_HELP = "between 0 (valid) and 1 (all), like OpenCV's alpha / fisheye balance"
FOCAL_HELP = "a given focal length [px] of the rectified camera (centred)"


def register(sub) -> None:
    p = sub.add_parser("undistort", help="rectified images and undistortion maps of a calibration",
                       description="Rectify photos to an ideal pinhole camera (any calibration method), and "
                                   "export the maps (maps.npz; map_x.tiff/map_y.tiff float32 for cv2.remap).")
    p.add_argument("calibration", help="freecal.calibration/1 JSON file (- : standard input)")
    p.add_argument("images", nargs="*", help="photos to rectify (the calibration's image size)")
    p.add_argument("-o", "--output", required=True, help="output directory")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--keep", choices=sorted([*KEEP, "covered"]), help=KEEP_HELP)
    g.add_argument("--alpha", type=float, help=ALPHA_HELP)
    g.add_argument("--focal", type=float, help=FOCAL_HELP)
    p.add_argument("--size", help="rectified image size WxH (default: the photo's)")
    p.add_argument("--maps", action="store_true", help="also write the maps (always written when no images are given)")
    p.add_argument("--json", action="store_true", help="print the rectified camera and the files written as JSON")
    p.set_defaults(run=run)


def parse_size(text: str | None) -> tuple[int, int] | None:
    if not text:
        return None
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise SettingsError(f"--size: expected WIDTHxHEIGHT such as 1024x1280, got {text!r}") from None
    return w, h


def chosen_camera(cal, keep: str | None, alpha: float | None, focal: float | None,
                  size: tuple[int, int] | None, hull=None) -> RectifiedCamera:
    """The rectified camera the flags ask for (--keep, --alpha, --focal: one at most; default valid);
    ``hull``: the covered region for --keep covered (default: the calibration's record)."""
    if focal is not None:
        return fixed_camera(focal, size or photo_size(cal))
    if keep == "covered":
        return covered_camera(cal, size, hull)
    return rectified_camera(cal, alpha if alpha is not None else KEEP[keep or "valid"], size)


def run(args) -> int:
    import cv2

    outputs = Outputs()
    folder = outputs.folder(args.output, "-o")
    assert folder is not None  # -o is required
    if args.json:
        claim_stdout("--json")
    cal = load_calibration(args.calibration)
    camera = chosen_camera(cal, args.keep, args.alpha, args.focal, parse_size(args.size))
    maps = undistort_maps(cal, camera)
    with outputs.writing():
        out = folder.staging()  # everything lands in the folder together at the end
        (out / "rectified_camera.json").write_text(json.dumps(camera.to_json(), indent=1) + "\n")
        written = [out / "rectified_camera.json"]
        if args.maps or not args.images:
            written += save_maps(out, *maps, camera)
        for name in args.images:
            image = _read_image(name)
            if image is None:
                raise RectifyError(f"{name}: not an image OpenCV can read")
            target = out / Path(name).name
            if not cv2.imwrite(str(target), rectify_image(cal, image, camera, maps)):
                raise RectifyError(f"could not write {Path(args.output) / target.name}")
            written.append(target)
    files = [str(folder.target / p.name) for p in written]
    if args.json:
        print_json({"rectified_camera": camera.to_json(), "written": files})
        return 0
    print(f"rectified camera: focal {camera.focal:.3f} px, centre ({camera.cx:.3f}, {camera.cy:.3f}), "
          f"{camera.width} x {camera.height}")
    if camera.note:
        print(f"note: {camera.note}")
    for path in files:
        print(f"wrote {path}")
    return 0


def _read_image(name: str):
    """The image in ``name`` as it is (colour, bit depth), None if OpenCV cannot decode it; one that
    declares more pixels than OpenCV may decode is refused in detect's words (read_gray's TooManyPixels)."""
    import cv2

    from calib_core.detection.detect_image import TooManyPixels, read_gray

    try:
        return cv2.imread(name, cv2.IMREAD_UNCHANGED)
    except cv2.error as exc:
        if "MAX_IMAGE" not in str(exc):
            raise
    try:
        read_gray(name)  # refuses it from the header alone, with the limit and what to do
    except TooManyPixels as exc:
        raise RectifyError(f"{name}: {exc}") from None
    raise RectifyError(f"{name}: more pixels than OpenCV may decode: downscale it")

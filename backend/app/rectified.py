"""What a done job's calibration does to its photos: rectified previews,
undistortion maps and the geometric quality of the rectified boards (Table 7).
Computed on request from the job's files and cached beside them (DATA/jobs/ID/
rectified/NAME.jpg, DATA/jobs/ID/maps.npz)."""
from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from calib_core import Calibration, Observations
from calib_core.errors import CalibError
from calib_core.evaluation.quality import geometric_quality, raw_quality
from calib_core.products.rectify import fixed_camera, photo_size, rectified_camera, rectify_image, undistort_maps

from ..base import storage
from .image_header import check_decodable

PREVIEW_SIZE = 640  # pixels on the longest side


def _camera(cal: Calibration):
    """alpha = 0 (only valid pixels: the view a user compares with the photo);
    if the model folds at the image border, alpha = 1; failing that, the
    calibration's own focal length on the photo's size."""
    for alpha in (0.0, 1.0):
        try:
            return rectified_camera(cal, alpha=alpha)
        except CalibError:
            continue
    fx, fy = cal.model.intrinsics[:2]
    return fixed_camera(0.5 * (fx + fy), photo_size(cal))


def preview(job_dir: Path, image: Path, max_pixels: int) -> bytes | None:
    """A JPEG of ``image`` rectified by the job's calibration (cached), or None
    if the image cannot be read (ApiError 413 when it has more than ``max_pixels``)."""
    out = job_dir / "rectified" / f"{image.name}.jpg"
    if out.exists():
        return out.read_bytes()
    if not image.is_file():
        return None
    check_decodable(image, image.name, max_pixels)  # the API never decodes past the limit (thumbnails.py)
    photo = cv2.imread(str(image), cv2.IMREAD_COLOR)
    if photo is None:
        return None
    cal = Calibration.load(job_dir / "calibration.json")
    rectified = rectify_image(cal, photo, _camera(cal))
    scale = PREVIEW_SIZE / max(rectified.shape[:2])
    if scale < 1:
        rectified = cv2.resize(rectified, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    ok, buf = cv2.imencode(".jpg", rectified, [cv2.IMWRITE_JPEG_QUALITY, 85])
    if not ok:
        return None
    return storage.write_cache(out, buf.tobytes())  # atomic: a reader never sees half a file


def maps_npz(job_dir: Path) -> Path:
    """The undistortion maps (float32 map_x, map_y: for each rectified pixel the
    photo pixel) and the rectified camera, as an .npz for cv2.remap. Made once and
    kept as a result file: a large photo's maps take seconds and gigabytes to compute."""
    out = job_dir / "maps.npz"
    if out.exists():
        return out
    cal = Calibration.load(job_dir / "calibration.json")
    camera = _camera(cal)
    map_x, map_y = undistort_maps(cal, camera)
    buf = io.BytesIO()
    np.savez_compressed(buf, map_x=map_x.astype(np.float32), map_y=map_y.astype(np.float32),
                        camera_matrix=camera.matrix, size=np.array(camera.size))
    storage.write_bytes(out, buf.getvalue())
    return out


def quality(job_dir: Path, observations: Path) -> dict[str, Any]:
    """Table 7 for the job's calibration and for the raw photos, on its corners."""
    cal = Calibration.load(job_dir / "calibration.json")
    obs = Observations.load(observations)
    return {"method": cal.method, "calibrated": geometric_quality(cal, obs), "raw": raw_quality(obs)}

"""A rig for the tools that read several cameras at once: Kalibr's camchain
(every camera, each with ``T_cn_cnm1`` from the one before) and OpenCV's
stereo FileStorage (two cameras: ``M1, D1, M2, D2, R, T`` as
``samples/cpp/stereo_calib.cpp`` writes them, what ``cv2.stereoRectify``
takes). Each camera is exported as ``export`` writes it alone (its own model
when the tool knows it, else the closest fitted one, with the fit's error)."""
from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import CalibError, SettingsError
from ..rig import Rig
from ..rig.poses import compose, inverse
from .kalibr import camera_entry
from .targets import Export, closeness, export
from .text import fit_note

RIG_TARGETS = ("kalibr", "opencv")


@dataclass
class RigExport:
    to: str
    text: str
    cameras: list[Export]  # each camera's export, in the rig's order


def export_rig(rig: Rig, to: str, model: str = "auto") -> RigExport:
    if to not in RIG_TARGETS:
        raise SettingsError(f"a rig exports to {' or '.join(RIG_TARGETS)} (several cameras in one file), not {to!r}; "
                            "export one camera by saving its calibration (cameras[i].calibration) alone")
    done = [export(cam.calibration, to, model) for cam in rig.cameras]
    if to == "kalibr":
        return RigExport(to, _camchain(rig, done), done)
    if len(rig.cameras) != 2:
        raise SettingsError(f"OpenCV's stereo file holds two cameras; this rig has {len(rig.cameras)}: "
                            "use --to kalibr for every camera in one camchain")
    if model == "auto" and len({_family(e) for e in done}) > 1:
        done = _one_family(rig, done)
    return RigExport(to, _stereo(rig, done), done)


def _family(e: Export) -> str:
    return "fisheye" if e.fit.name == "kb4" else "opencv"


def _one_family(rig: Rig, done: list[Export]) -> list[Export]:
    """Both cameras as OpenCV's model, or both as Kannala–Brandt: cv2.stereoRectify takes the one,
    cv2.fisheye.stereoRectify the other, and neither a pair of both. Of the two, the one whose
    worse camera strays least (``closeness``)."""
    pairs = []
    for name, family in (("opencv8", "opencv"), ("kb4", "fisheye")):
        try:
            pairs.append([e if _family(e) == family else export(cam.calibration, "opencv", name)
                          for cam, e in zip(rig.cameras, done, strict=True)])
        except CalibError:  # a camera this model cannot take (a rational fit with a pole among its corners)
            continue
    if not pairs:
        raise SettingsError("the two cameras take different OpenCV models (one fisheye), and neither model fits both: "
                            "a stereo pair for cv2.stereoRectify needs one; export each camera alone")
    return min(pairs, key=lambda pair: max(closeness(e.fit) for e in pair))


def _matrix(pose: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = Rotation.from_rotvec(pose[:3]).as_matrix()
    out[:3, 3] = pose[3:]
    return out


# Kalibr's lengths are metres; a rig's are its board's units (``provenance.tvec_units``).
METRES = {"mm": 1e-3, "cm": 1e-2, "m": 1.0}


def _camchain(rig: Rig, done: list[Export]) -> str:
    units = rig.cameras[0].calibration.provenance.get("tvec_units")
    if units not in METRES:
        raise SettingsError(f"Kalibr's camchain gives the cameras' offsets in metres, and this rig's lengths are in "
                            f"{units or 'units it does not record'}: give the observations' board its units "
                            "(\"units\": \"mm\", formats.md section 1) and calibrate the rig again")
    overlaps = rig.diagnostics.get("overlaps", {})
    names = [c.name for c in rig.cameras]
    text = "".join(f"# cam{k} = {json.dumps(c.name)}: {fit_note(e.fit)}\n" for k, (c, e) in enumerate(zip(rig.cameras, done, strict=True)))
    text += f"# T_cn_cnm1: metres (the rig was calibrated in {units})\n"
    for k, (cam, e) in enumerate(zip(rig.cameras, done, strict=True)):
        previous = None if k == 0 else _matrix(compose(cam.pose, inverse(rig.cameras[k - 1].pose)))
        if previous is not None:
            previous[:3, 3] *= METRES[units]
        shared = [names.index(n) for n in overlaps.get(cam.name, names) if n != cam.name and n in names]
        text += camera_entry(k, e.fit, f"/{cam.name}/image_raw", shared, previous)
    return text


def _stereo(rig: Rig, done: list[Export]) -> str:
    import cv2

    first, second = rig.cameras
    relative = compose(second.pose, inverse(first.pose))
    fs = cv2.FileStorage("stereo.yaml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    for k, e in enumerate(done, start=1):
        model = e.fit.parametric
        fx, fy, cx, cy, skew = model.intrinsics
        fs.write(f"camera_{k}", rig.cameras[k - 1].name)
        fs.write(f"image_width_{k}", int(e.fit.image_size[0]))
        fs.write(f"image_height_{k}", int(e.fit.image_size[1]))
        fs.write(f"distortion_model_{k}", e.consumer_model)
        fs.write(f"M{k}", np.array([[fx, skew, cx], [0, fy, cy], [0, 0, 1.0]]))
        fs.write(f"D{k}", np.asarray(model.coefficients, dtype=np.float64).reshape(1, -1))
        fs.write(f"fit_{k}", fit_note(e.fit))
    fs.write("R", Rotation.from_rotvec(relative[:3]).as_matrix())
    fs.write("T", relative[3:].reshape(3, 1))
    fs.write("T_units", str(first.calibration.provenance.get("tvec_units", "the board's units")))
    fs.write("rms_px", float(rig.metrics.rmse))
    return fs.releaseAndGetString()

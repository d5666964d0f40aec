"""The consumers' own readings of freecal's exports, re-implemented from their
sources (cited per function) where the consumer cannot run here: parsing as
they parse, the schema checks their readers make, and their projection of a
camera-frame ray to a pixel, in freecal's pixel convention (the centre of the
top-left pixel at (0, 0))."""
from __future__ import annotations

import json

import numpy as np
import yaml

EPS = np.finfo(np.float64).eps


# ---- COLMAP: src/colmap/sensor/models.h, src/colmap/scene/reconstruction_io.cc ------------------------
def colmap_cameras(text: str) -> dict[int, dict]:
    """cameras.txt as COLMAP's ReadCamerasText reads it: '#' lines and blank lines skipped,
    then CAMERA_ID MODEL WIDTH HEIGHT PARAMS[] separated by whitespace."""
    out = {}
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        tok = line.split()
        out[int(tok[0])] = {"model": tok[1], "width": int(tok[2]), "height": int(tok[3]),
                            "params": np.array([float(t) for t in tok[4:]])}
    return out


COLMAP_N_PARAMS = {"OPENCV": 8, "FULL_OPENCV": 12, "OPENCV_FISHEYE": 8}


def colmap_project(camera: dict, xyz: np.ndarray) -> np.ndarray:
    """ImgFromCam of OPENCV, FULL_OPENCV, OPENCV_FISHEYE, minus COLMAP's half pixel; NaN where
    HasProjectableDepth (w ≥ eps, cheirality checked) fails."""
    p = camera["params"]
    assert len(p) == COLMAP_N_PARAMS[camera["model"]]
    f1, f2, c1, c2 = p[:4]
    u, v, w = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    ok = w >= EPS
    uu, vv = u / np.where(ok, w, 1.0), v / np.where(ok, w, 1.0)
    if camera["model"] == "OPENCV_FISHEYE":
        r = np.hypot(uu, vv)
        scale = np.where(r > EPS, np.arctan(r) / np.where(r > EPS, r, 1.0), 1.0)  # FisheyeFromNormal
        uu, vv = uu * scale, vv * scale
        k1, k2, k3, k4 = p[4:8]
        t2 = uu * uu + vv * vv
        radial = k1 * t2 + k2 * t2**2 + k3 * t2**3 + k4 * t2**4
        du, dv = uu * radial, vv * radial
    elif camera["model"] == "OPENCV":
        k1, k2, p1, p2 = p[4:8]
        u2, uv, v2 = uu * uu, uu * vv, vv * vv
        r2 = u2 + v2
        radial = k1 * r2 + k2 * r2 * r2
        du = uu * radial + 2 * p1 * uv + p2 * (r2 + 2 * u2)
        dv = vv * radial + 2 * p2 * uv + p1 * (r2 + 2 * v2)
    else:  # FULL_OPENCV
        k1, k2, p1, p2, k3, k4, k5, k6 = p[4:12]
        u2, uv, v2 = uu * uu, uu * vv, vv * vv
        r2 = u2 + v2
        r4, r6 = r2 * r2, r2 * r2 * r2
        radial = (1 + k1 * r2 + k2 * r4 + k3 * r6) / (1 + k4 * r2 + k5 * r4 + k6 * r6)
        du = uu * radial + 2 * p1 * uv + p2 * (r2 + 2 * u2) - uu
        dv = vv * radial + 2 * p2 * uv + p1 * (r2 + 2 * v2) - vv
    q = np.column_stack([f1 * (uu + du) + c1, f2 * (vv + dv) + c2]) - 0.5
    q[~ok] = np.nan
    return q


# ---- nerfstudio: nerfstudio/cameras/cameras.py, cameras/camera_utils.py, dataparsers ------------------
def nerfstudio_camera(text: str) -> dict:
    """transforms.json's shared camera fields, as NerfstudioDataParser reads them."""
    meta = json.loads(text)
    for key in ("fl_x", "fl_y", "cx", "cy", "w", "h", "camera_model"):
        assert key in meta, key
    assert meta["camera_model"] in ("OPENCV", "OPENCV_FISHEYE")
    assert isinstance(meta["w"], int) and isinstance(meta["h"], int) and isinstance(meta["frames"], list)
    # camera_utils.get_distortion_params: [k1, k2, k3, k4, p1, p2], missing ones 0
    meta["distortion_params"] = np.array([float(meta.get(k, 0.0)) for k in ("k1", "k2", "k3", "k4", "p1", "p2")])
    return meta


def _nerfstudio_distort(x, y, d):
    """The forward model ``_compute_residual_and_jacobian`` inverts: (xd, yd) of (x, y)."""
    k1, k2, k3, k4, p1, p2 = d
    r = x * x + y * y
    dd = 1.0 + r * (k1 + r * (k2 + r * (k3 + r * k4)))
    return dd * x + 2 * p1 * x * y + p2 * (r + 2 * x * x), dd * y + 2 * p2 * x * y + p1 * (r + 2 * y * y)


def nerfstudio_project(meta: dict, xyz: np.ndarray) -> np.ndarray:
    """The pixel (freecal's convention) whose ray nerfstudio casts along ``xyz``: PERSPECTIVE
    undistorts (x/z, y/z); FISHEYE undistorts θ (cos φ, sin φ) (``_generate_rays_from_coords``);
    pixels are cast from index + 0.5."""
    if meta["camera_model"] == "OPENCV_FISHEYE":
        theta = np.arctan2(np.hypot(xyz[:, 0], xyz[:, 1]), xyz[:, 2])
        phi = np.arctan2(xyz[:, 1], xyz[:, 0])
        x, y = theta * np.cos(phi), theta * np.sin(phi)
    else:
        x, y = xyz[:, 0] / xyz[:, 2], xyz[:, 1] / xyz[:, 2]
    xd, yd = _nerfstudio_distort(x, y, meta["distortion_params"])
    return np.column_stack([meta["fl_x"] * xd + meta["cx"], meta["fl_y"] * yd + meta["cy"]]) - 0.5


def nerfstudio_rays(meta: dict, pixels: np.ndarray) -> np.ndarray:
    """Unit rays (N, 3), OpenCV's camera frame, that nerfstudio casts through freecal pixels:
    (x − cx)/fx of index + 0.5, ``radial_and_tangential_undistort`` (10 Newton steps from the
    distorted point), then the PERSPECTIVE or FISHEYE direction (before its OpenGL flip)."""
    d = meta["distortion_params"]
    k1, k2, k3, k4, p1, p2 = d
    xd = (pixels[:, 0] + 0.5 - meta["cx"]) / meta["fl_x"]
    yd = (pixels[:, 1] + 0.5 - meta["cy"]) / meta["fl_y"]
    x, y = xd.copy(), yd.copy()
    for _ in range(10):
        r = x * x + y * y
        dd = 1.0 + r * (k1 + r * (k2 + r * (k3 + r * k4)))
        fx = dd * x + 2 * p1 * x * y + p2 * (r + 2 * x * x) - xd
        fy = dd * y + 2 * p2 * x * y + p1 * (r + 2 * y * y) - yd
        d_r = k1 + r * (2.0 * k2 + r * (3.0 * k3 + r * 4.0 * k4))
        d_x, d_y = 2.0 * x * d_r, 2.0 * y * d_r
        fx_x = dd + d_x * x + 2.0 * p1 * y + 6.0 * p2 * x
        fx_y = d_y * x + 2.0 * p1 * x + 2.0 * p2 * y
        fy_x = d_x * y + 2.0 * p2 * y + 2.0 * p1 * x
        fy_y = dd + d_y * y + 2.0 * p2 * x + 6.0 * p1 * y
        den = fy_x * fx_y - fx_x * fy_y
        big = np.abs(den) > 1e-3
        x = x + np.where(big, (fx * fy_y - fy * fx_y) / np.where(big, den, 1.0), 0.0)
        y = y + np.where(big, (fy * fx_x - fx * fy_x) / np.where(big, den, 1.0), 0.0)
    if meta["camera_model"] == "OPENCV_FISHEYE":
        theta = np.clip(np.hypot(x, y), 0.0, np.pi)
        s = np.sin(theta) / np.where(theta > 0, theta, 1.0)
        rays = np.column_stack([x * s, y * s, np.cos(theta)])
    else:
        rays = np.column_stack([x, y, np.ones_like(x)])
    return rays / np.linalg.norm(rays, axis=1, keepdims=True)


# ---- Kalibr: kalibr_common/ConfigReader.py, aslam_cameras (PinholeProjection, *Distortion) ------------
def kalibr_camera(text: str, nr: int = 0) -> dict:
    """One camera of a camchain, with the checks CameraParameters makes on reading."""
    chain = yaml.safe_load(text)
    cam = chain[f"cam{nr}"]
    assert cam["camera_model"] in ("pinhole", "omni", "eucm", "ds")
    intr = cam["intrinsics"]
    assert cam["camera_model"] == "pinhole" and len(intr) == 4  # [fu, fv, pu, pv]
    assert all(isinstance(v, float) for v in intr), "Kalibr: invalid focalLength / principalPoint (floats)"
    assert intr[0] >= 0 and intr[1] >= 0 and intr[2] >= 0 and intr[3] >= 0
    n = {"radtan": 4, "equidistant": 4, "fov": 1, "none": 0}[cam["distortion_model"]]
    assert len(cam["distortion_coeffs"]) == n
    res = cam["resolution"]
    assert len(res) == 2 and all(isinstance(v, int) for v in res)
    assert isinstance(cam["rostopic"], str)
    return cam


def kalibr_project(cam: dict, xyz: np.ndarray) -> np.ndarray:
    """PinholeProjection::euclideanToKeypoint with RadialTangential/EquidistantDistortion::distort;
    NaN where p_z ≤ 0."""
    fu, fv, cu, cv = cam["intrinsics"]
    y0, y1 = xyz[:, 0] / xyz[:, 2], xyz[:, 1] / xyz[:, 2]
    if cam["distortion_model"] == "radtan":
        k1, k2, p1, p2 = cam["distortion_coeffs"]
        mx2, my2, mxy = y0 * y0, y1 * y1, y0 * y1
        rho2 = mx2 + my2
        rad = k1 * rho2 + k2 * rho2 * rho2
        y0, y1 = (y0 + y0 * rad + 2.0 * p1 * mxy + p2 * (rho2 + 2.0 * mx2),
                  y1 + y1 * rad + 2.0 * p2 * mxy + p1 * (rho2 + 2.0 * my2))
    else:
        k1, k2, k3, k4 = cam["distortion_coeffs"]
        r = np.sqrt(y0 * y0 + y1 * y1)
        theta = np.arctan(r)
        t2 = theta * theta
        thetad = theta * (1 + k1 * t2 + k2 * t2**2 + k3 * t2**3 + k4 * t2**4)
        scaling = np.where(r > 1e-8, thetad / np.where(r > 1e-8, r, 1.0), 1.0)
        y0, y1 = y0 * scaling, y1 * scaling
    q = np.column_stack([fu * y0 + cu, fv * y1 + cv])
    q[xyz[:, 2] <= 0] = np.nan
    return q


# ---- ROS: camera_calibration_parsers (parse_yml.cpp) ------------------------------------------------
def ros_camera_info(text: str) -> dict:
    """camera_info YAML with the fields and shapes camera_calibration_parsers requires."""
    doc = yaml.safe_load(text)
    assert isinstance(doc["image_width"], int) and isinstance(doc["image_height"], int)
    assert isinstance(doc["camera_name"], str)
    assert doc["distortion_model"] in ("plumb_bob", "rational_polynomial", "equidistant")
    out = dict(doc)
    for name, shape in (("camera_matrix", (3, 3)), ("rectification_matrix", (3, 3)), ("projection_matrix", (3, 4)),
                        ("distortion_coefficients", None)):
        m = doc[name]
        assert isinstance(m["rows"], int) and isinstance(m["cols"], int) and len(m["data"]) == m["rows"] * m["cols"]
        if shape is not None:
            assert (m["rows"], m["cols"]) == shape, name
        out[name] = np.array(m["data"], dtype=np.float64).reshape(m["rows"], m["cols"])
    return out

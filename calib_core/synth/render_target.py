"""Photo-like images of a calibration object of several boards (``freecal.target/1``),
or of one ChArUco or AprilGrid board, through the synthetic lenses.

Like ``render.py`` (inverse mapping, every pixel's ray from the lens), but
each board is a printed texture: OpenCV draws a ChArUco board
(``CharucoBoard.generateImage``), an AprilGrid is drawn as Kalibr prints it
(``aprilgrid_texture``), a chessboard as squares. A pixel's ray meets every
board's plane; the nearest board whose paper it hits gives its grey level,
read from the texture at SUPERSAMPLE² points spread over the pixel's
footprint (a box filter; texel edges fall exactly on the board's square and
tag edges, so corners are where the geometry puts them). A board seen from
behind shows plain paper. Then blur and noise as in ``render.py``.
"""
from __future__ import annotations

import functools

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from ..board import BoardSpec
from ..detection.aprilgrid import BORDER_BITS
from ..target import Target
from . import render
from .lenses import IMAGE_SIZE

TEXELS_PER_SQUARE = 40     # at least, per ChArUco and chessboard square; an AprilGrid tag gets 10 per bit
PAPER = 0.5                # white margin round a board, in squares (tags for an AprilGrid): a cube face's edge
BACK = 150.0               # grey of a board's back


@functools.lru_cache(maxsize=32)
def texture(spec: BoardSpec) -> tuple[np.ndarray, float, float]:
    """A board's printed face: grey levels (rows, cols) float32 with the paper
    margin, the texel's size in board units, and the board coordinate of the
    texture's first texel edge (the same along x and y). Texel (i, j) covers
    board x in origin + [j, j+1)·texel, y in origin + [i, i+1)·texel."""
    black, white = render.BLACK, render.WHITE
    start = 0.0
    if spec.type == "aprilgrid":
        tex, texel, start = aprilgrid_texture(spec)
        margin = int(round(PAPER * spec.square_size / texel))
    else:
        per = _texels_per_square(spec)
        texel = spec.square_size / per
        squares = (spec.cols + 1, spec.rows + 1) if spec.type == "chessboard" else (spec.cols, spec.rows)
        if spec.type == "charuco":
            tex = spec.cv_charuco().generateImage((squares[0] * per, squares[1] * per), marginSize=0, borderBits=1)
        else:  # the square whose top-left corner is corner (r, c) is bright iff r + c is even (render.py)
            i, j = np.indices((squares[1], squares[0]))
            tex = np.kron(np.where((i + j) % 2 == 0, 255, 0), np.ones((per, per))).astype(np.uint8)
            start = -spec.square_size            # the squares round corner 0 start a square before it
        margin = int(round(PAPER * per))
    tex = np.where(tex > 127, white, black).astype(np.float32)
    tex = np.pad(tex, margin, constant_values=white)
    return tex, texel, start - margin * texel


def _texels_per_square(spec: BoardSpec) -> int:
    """At least TEXELS_PER_SQUARE, and for ChArUco so many that the markers' margin and bits
    are whole texels: OpenCV then draws every marker exactly where the board's geometry has it."""
    if spec.type != "charuco":
        return TEXELS_PER_SQUARE
    bits = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, str(spec.dictionary))).markerSize + 2
    marker = float(spec.marker_size or 0.0) / spec.square_size
    for per in range(TEXELS_PER_SQUARE, 20 * TEXELS_PER_SQUARE):
        margin, bit = per * (1 - marker) / 2, per * marker / bits
        if abs(margin - round(margin)) < 1e-6 and abs(bit - round(bit)) < 1e-6:
            return per
    return TEXELS_PER_SQUARE


def aprilgrid_texture(spec: BoardSpec) -> tuple[np.ndarray, float, float]:
    """An AprilGrid as Kalibr prints it (``kalibr_create_target_pdf``), 0 black / 255
    white, rows along the page's **y (up)**, the texel size and the page coordinate
    of its first texel (the outer corner squares lie outside the tags, at −gap).

    Tag ``t`` at (col, row) = (t % X, t // X) from the bottom-left; its image is
    OpenCV's marker turned by 180° on the page (checked against Kalibr's codes),
    i.e. ``fliplr`` of it in rows that run up the page; black squares of the gap's
    size at its four corners."""
    bits = 6 + 2 * BORDER_BITS
    per_bit = 10
    tag = bits * per_bit
    texel = spec.square_size / tag
    gap = int(round(float(spec.tag_spacing or 0.0) * tag))
    step = tag + gap
    page = np.full((spec.rows * step - gap, spec.cols * step - gap), 255, np.uint8)
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, str(spec.dictionary)))
    for t in range(spec.n_markers):
        row, col = divmod(t, spec.cols)
        marker = cv2.aruco.generateImageMarker(dictionary, spec.first_marker + t, tag, borderBits=BORDER_BITS)
        y0, x0 = row * step, col * step
        page[y0:y0 + tag, x0:x0 + tag] = np.fliplr(marker)
    page = np.pad(page, gap, constant_values=255)
    for y in range(spec.rows + 1):          # the corner squares, between and round the tags
        for x in range(spec.cols + 1):
            page[y * step:y * step + gap, x * step:x * step + gap] = 0
    return page, texel, -gap * texel


def _board_hits(rays: np.ndarray, board_to_camera: np.ndarray, spec: BoardSpec):
    """Depth along each ray (H, W) where it meets the board's paper (inf: misses),
    board coordinates (H, W, 2), and whether the printed side faces the ray (H, W)."""
    r = Rotation.from_rotvec(board_to_camera[:3]).as_matrix()
    t = board_to_camera[3:]
    normal = r[:, 2]                       # the board's +z in the camera
    denom = rays @ normal
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = (normal @ t) / denom
    hit = np.isfinite(depth) & (depth > 0)
    p = rays * np.where(hit, depth, 0.0)[..., None] - t
    b = p @ r[:, :2]                       # (R^T (p − t))[:2]
    tex, texel, origin = texture(spec)
    lo, hi = origin, origin + np.array([tex.shape[1], tex.shape[0]]) * texel
    hit &= np.all((b >= lo) & (b < hi), axis=-1)
    # OpenCV's boards face −z of their frame; Kalibr's AprilGrid (x right, y up the page) faces +z.
    front = denom < 0 if spec.type == "aprilgrid" else denom > 0
    return np.where(hit, depth, np.inf), b, front


def _lookup(spec: BoardSpec, b: np.ndarray) -> np.ndarray:
    tex, texel, origin = texture(spec)
    j = np.clip(np.floor((b[..., 0] - origin) / texel).astype(np.int64), 0, tex.shape[1] - 1)
    i = np.clip(np.floor((b[..., 1] - origin) / texel).astype(np.int64), 0, tex.shape[0] - 1)
    return tex[i, j]


def render_target(kind: str, target: Target, pose: np.ndarray, rng: np.random.Generator | None = None,
                  blur: float = render.BLUR_SIGMA, noise: float = render.NOISE_SIGMA,
                  image_size: tuple[int, int] = IMAGE_SIZE) -> np.ndarray:
    """8-bit image (H, W) of the target's fixed boards, the object at ``pose`` (object → camera)."""
    boards = [(b.spec, _compose(pose, np.asarray(b.pose))) for b in target.boards if b.pose is not None]
    return render_boards(kind, boards, rng, blur, noise, image_size)


def render_boards(kind: str, boards: list[tuple[BoardSpec, np.ndarray]], rng: np.random.Generator | None = None,
                  blur: float = render.BLUR_SIGMA, noise: float = render.NOISE_SIGMA,
                  image_size: tuple[int, int] = IMAGE_SIZE) -> np.ndarray:
    """8-bit image (H, W) of boards, each (spec, pose board → camera)."""
    rays, covered = render.unit_rays(kind, image_size)
    hits = [_board_hits(rays, pose, spec) for spec, pose in boards]
    depth = np.stack([h[0] for h in hits])                        # (B, H, W)
    nearest = np.argmin(depth, axis=0)
    seen = np.isfinite(np.min(depth, axis=0)) & covered
    img = np.full(seen.shape, render.BACKDROP, np.float32)
    offsets = (np.arange(render.SUPERSAMPLE) + 0.5) / render.SUPERSAMPLE - 0.5
    for k, ((spec, _), (_, b, front)) in enumerate(zip(boards, hits, strict=True)):
        mine = seen & (nearest == k)
        img[mine & ~front] = BACK
        mine &= front
        if not mine.any():
            continue
        du, dv = np.gradient(b, axis=1)[mine], np.gradient(b, axis=0)[mine]   # the pixel's footprint on the board
        bb, acc = b[mine], np.zeros(int(mine.sum()))
        for oy in offsets:
            for ox in offsets:
                acc += _lookup(spec, bb + ox * du + oy * dv)
        img[mine] = acc / render.SUPERSAMPLE ** 2
    img[~covered] = 0.0
    if blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur)
    if noise > 0:
        img = img + (rng or np.random.default_rng(0)).normal(0.0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def _compose(object_to_camera: np.ndarray, board_to_object: np.ndarray) -> np.ndarray:
    """The pose board → camera of a board fixed to an object at ``object_to_camera``."""
    ro, rb = Rotation.from_rotvec(object_to_camera[:3]), Rotation.from_rotvec(board_to_object[:3])
    return np.concatenate([(ro * rb).as_rotvec(), ro.apply(board_to_object[3:]) + object_to_camera[3:]])

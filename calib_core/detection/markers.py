"""ArUco and AprilTag markers: found once per image and dictionary, shared by
every board that uses them, and, when none is found, why (in words).

Several boards of one dictionary in one image (``freecal.target/1``) each take
their own id range from the same detection (``Markers.of``). When a board's
markers are not found, the image is searched for what it does show: markers
of another common dictionary (a wrong ``--board``), or the board's own
markers read mirrored (a board seen from behind through the paper, or printed
mirrored): the reason says so. A board's decoded markers are checked against
its layout (``layout_verdict``): markers read on a board of another size sit
where that board has other ids.
"""
from __future__ import annotations

import threading

import cv2
import numpy as np

from ..board import APRILGRID_DICTIONARY

# Dictionaries looked for when a board's own are absent: the common families, largest of each.
OTHER_DICTIONARIES = ("DICT_4X4_1000", "DICT_5X5_1000", "DICT_6X6_1000", "DICT_7X7_1000", "DICT_ARUCO_ORIGINAL",
                      "DICT_APRILTAG_36h11", "DICT_APRILTAG_25h9", "DICT_APRILTAG_16h5")
FAMILY = {"DICT_4X4": "DICT_4X4_1000", "DICT_5X5": "DICT_5X5_1000", "DICT_6X6": "DICT_6X6_1000",
          "DICT_7X7": "DICT_7X7_1000"}


_per_thread = threading.local()


def detector(dictionary: str, border_bits: int = 1) -> cv2.aruco.ArucoDetector:
    """A marker detector, one per thread (images are detected on several threads, and OpenCV
    does not promise that one detector object may run on two at once)."""
    made = _per_thread.__dict__.setdefault("detectors", {})
    key = (dictionary, border_bits)
    if key not in made:
        params = cv2.aruco.DetectorParameters()
        params.markerBorderBits = border_bits
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        made[key] = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary)), params)
    return made[key]


def detect(gray: np.ndarray, dictionary: str, border_bits: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Marker corners (M, 4, 2) float32 (OpenCV's order: the marker's top-left,
    top-right, bottom-right, bottom-left) and ids (M,) int64."""
    corners, ids, _ = detector(dictionary, border_bits).detectMarkers(gray)
    if ids is None or len(ids) == 0:
        return np.zeros((0, 4, 2), np.float32), np.zeros(0, np.int64)
    return np.asarray(corners, np.float32).reshape(-1, 4, 2), ids.reshape(-1).astype(np.int64)


class Markers:
    """The markers of one image, detected on first use per (dictionary, border bits)."""

    def __init__(self, gray: np.ndarray):
        self.gray = gray
        self._found: dict[tuple[str, int], tuple[np.ndarray, np.ndarray]] = {}

    def all(self, dictionary: str, border_bits: int = 1) -> tuple[np.ndarray, np.ndarray]:
        key = (dictionary, border_bits)
        if key not in self._found:
            self._found[key] = detect(self.gray, dictionary, border_bits)
        return self._found[key]

    def of(self, dictionary: str, first: int, count: int, border_bits: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """The markers with ids first … first + count − 1."""
        corners, ids = self.all(dictionary, border_bits)
        mine = (ids >= first) & (ids < first + count)
        return corners[mine], ids[mine]


def why_none(gray: np.ndarray, dictionary: str, border_bits: int = 1, first: int = 0, count: int | None = None,
             markers: Markers | None = None) -> str:
    """Why no marker of ``dictionary`` (ids ``first`` … ``first + count − 1``) was found, in words."""
    found = markers.all(dictionary, border_bits)[1] if markers is not None else detect(gray, dictionary, border_bits)[1]
    if count is not None and len(found) >= 3:   # (one or two: likely specks read as markers)
        return (f"no markers of this board (ids {first}-{first + count - 1} of {dictionary}); the image shows ids "
                f"{_ids(found)}: another board, or one whose markers start at another id (give its first_marker in "
                "a board or target file: docs/targets.md)")
    if len(detect(cv2.flip(gray, 1), dictionary, border_bits)[1]) >= 3:
        return (f"its {dictionary} markers read mirrored: the board is seen from behind (through the paper) or was "
                "printed mirrored")
    def ids_of(d: str, bits: int) -> np.ndarray:
        return markers.all(d, bits)[1] if markers is not None else detect(gray, d, bits)[1]

    other_bits = 3 - border_bits  # ChArUco's markers have a one-bit black border, Kalibr's AprilGrid tags two
    if len(ids_of(dictionary, other_bits)) >= 3:
        return (f"its {dictionary} markers have a {'two' if other_bits == 2 else 'one'}-bit black border: "
                + ("an AprilGrid's tags (give an aprilgrid board spec)" if other_bits == 2 else
                   "a ChArUco board's markers (give a charuco board spec)"))
    if border_bits == 1 and len(tags := ids_of(APRILGRID_DICTIONARY, 2)) >= 3:
        return (f"no {dictionary} markers decoded, but {len(tags)} tags of an AprilGrid ({APRILGRID_DICTIONARY}, with "
                "a two-bit border): check the board's type")
    seen = seen_instead(gray, dictionary, markers)
    if seen is not None:
        other, ids = seen
        return (f"no {dictionary} markers decoded, but {len(ids)} markers of {_smallest(other, ids)}: check the "
                "board's dictionary")
    return f"no {dictionary} markers decoded"


def seen_instead(gray: np.ndarray, dictionary: str, markers: Markers | None = None) -> tuple[str, np.ndarray] | None:
    """The first common dictionary other than ``dictionary``'s family (``OTHER_DICTIONARIES``) of
    which the image shows three markers or more, and their ids; None if none."""
    own = family(dictionary)
    for other in OTHER_DICTIONARIES:
        if other == own:
            continue
        ids = markers.all(other)[1] if markers is not None else detect(gray, other)[1]
        if len(ids) >= 3:
            return other, ids
    return None


def family(dictionary: str) -> str:
    """The largest dictionary of ``dictionary``'s family (DICT_6X6_250 → DICT_6X6_1000)."""
    return FAMILY.get(dictionary[:8], dictionary)


def _smallest(dictionary: str, ids: np.ndarray) -> str:
    """The smallest dictionary of ``dictionary``'s family holding ``ids`` (DICT_6X6_1000, ids < 50: DICT_6X6_50)."""
    if dictionary[:8] not in FAMILY:
        return dictionary
    size = next(n for n in (50, 100, 250, 1000) if ids.max() < n)
    return f"{dictionary[:8]}_{size}"


def _ids(ids: np.ndarray) -> str:
    u = np.unique(ids)
    return f"{u.min()}-{u.max()}" if len(u) > 1 else str(u[0])


# Markers checked against a board's layout: where more than this share of the checked pairs
# of decoded markers disagree (and more than one), the markers are not where the board puts
# them (a board of another size); fewer are misread markers, each dropped alone.
WRONG_LAYOUT = 0.25


def layout_verdict(first: np.ndarray, second: np.ndarray, agree: np.ndarray, n: int) -> tuple[np.ndarray, bool]:
    """(keep (n,) bool, wrong layout) from pairs of decoded markers (slots ``first``, ``second``
    (P,) in 0..n-1) checked against each other (``agree`` (P,) bool): a marker that disagrees
    with more of its pairs than it agrees with is dropped; a marker in no pair is kept."""
    def count(m: np.ndarray) -> np.ndarray:
        return np.bincount(first[m], minlength=n) + np.bincount(second[m], minlength=n)
    yes, no = count(agree), count(~agree)
    return yes >= no, bool(np.sum(~agree) > max(1, WRONG_LAYOUT * len(agree)))


def wrong_layout_reason(count: str, board: str, unit: str) -> str:
    """Why a board's markers (``count``: "17 markers") gave no view when they do not fit its layout, in words."""
    return f"board not found: its {count} are not where a {board} puts them; check the board's size ({unit} across × down)"


def homographies(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """(K, 3, 3) homographies of four point pairs each, src and dst (K, 4, 2): batched DLT."""
    k = len(src)
    a = np.zeros((k, 8, 8))
    x, y, u, v = src[..., 0], src[..., 1], dst[..., 0], dst[..., 1]
    a[:, 0::2, 0], a[:, 0::2, 1], a[:, 0::2, 2] = x, y, 1.0
    a[:, 1::2, 3], a[:, 1::2, 4], a[:, 1::2, 5] = x, y, 1.0
    a[:, 0::2, 6], a[:, 0::2, 7] = -u * x, -u * y
    a[:, 1::2, 6], a[:, 1::2, 7] = -v * x, -v * y
    b = np.stack([u, v], axis=-1).reshape(k, 8)
    h = np.linalg.solve(a, b[..., None])[..., 0] if k else np.zeros((0, 8))
    return np.concatenate([h, np.ones((k, 1))], axis=1).reshape(k, 3, 3)

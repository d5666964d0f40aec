"""Small JPEG previews of a set's images, made on first request and kept beside the set.

Cached under ``DATA/sets/ID/thumbs/SIZE/NAME.jpg`` (deleted with the set); a
preview older than its image is made again. OpenCV does the work: it is
already a dependency, and reads every format the uploads accept. Never more
pixels than the limit: the header is checked again before decoding (the limit
may have been lowered since the upload), and OpenCV's own limit is set in every
freecal process (backend/__init__.py).
"""
from __future__ import annotations

from pathlib import Path

from ..base import storage
from .image_header import check_decodable

SIZES = (160, 640)   # longest side in pixels: list thumbnails, and images to draw residuals on


def thumbnail(images_dir: Path, cache_dir: Path, name: str, size: int, max_pixels: int) -> bytes | None:
    """The preview (JPEG bytes), or None when the image is missing or unreadable
    (ApiError 413 when it has more than ``max_pixels``)."""
    import cv2

    src = images_dir / storage.safe_name(name)
    if not src.is_file():
        return None
    out = cache_dir / str(size) / (src.name + ".jpg")
    if out.is_file() and out.stat().st_mtime >= src.stat().st_mtime:
        return out.read_bytes()
    check_decodable(src, src.name, max_pixels)
    img = cv2.imread(str(src), cv2.IMREAD_COLOR)
    if img is None:
        return None
    h, w = img.shape[:2]
    k = size / max(w, h)
    if k < 1:
        img = cv2.resize(img, (max(1, round(w * k)), max(1, round(h * k))), interpolation=cv2.INTER_AREA)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 82])
    if not ok:
        return None
    return storage.write_cache(out, buf.tobytes())

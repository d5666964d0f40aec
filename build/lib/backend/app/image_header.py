"""What an image file's header says (its format and size), read without decoding a pixel.

The service decodes an image only if its header is one of the formats below and
declares at most ``FREECAL_MAX_IMAGE_PIXELS`` pixels: a 1 MB file can declare
20 000 x 20 000 pixels (a decompression bomb), and OpenCV would allocate them all.
OpenCV decodes more formats than these (JPEG 2000, OpenEXR, Radiance HDR, PFM,
PAM, GIF, ...): those are refused, because their size is not bounded here.

A sniffer of our own rather than Pillow: Pillow is not a dependency, it
recognises formats OpenCV does not decode (and the reverse), and what is needed
is six fixed header layouts, each a few lines.
"""
from __future__ import annotations

import re
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from .errors import ApiError

FORMATS = "PNG, JPEG, BMP, TIFF, WebP or PBM/PGM/PPM"


@dataclass(frozen=True)
class Header:
    format: str
    size: tuple[int, int] | None    # (width, height); None when the header ends before saying it


def read_header(path: Path) -> Header | None:
    """The image's format and size, or None when it is none of the formats the service decodes."""
    with open(path, "rb") as f:
        head = f.read(64)
        if head.startswith(b"\x89PNG\r\n\x1a\n"):
            return Header("PNG", struct.unpack(">II", head[16:24]) if head[12:16] == b"IHDR" and len(head) >= 24
                          else None)
        if head.startswith(b"\xff\xd8\xff"):
            return Header("JPEG", _jpeg_size(f))
        if head[:2] == b"BM":
            return Header("BMP", _bmp_size(head))
        if head[:4] in (b"II*\x00", b"MM\x00*"):
            return Header("TIFF", _tiff_size(f, "<" if head[:2] == b"II" else ">"))
        if head[:4] == b"RIFF" and head[8:12] == b"WEBP":
            return Header("WebP", _webp_size(head))
        if re.match(rb"P[1-6]\s", head):
            return Header("PNM", _pnm_size(f))
    return None


def check_decodable(path: Path, label: str, max_pixels: int) -> tuple[int, int]:
    """(width, height) of an image the service may decode, else ApiError saying why not:
    415 not a format it bounds, 422 a header without its size, 413 more pixels than the limit."""
    header = read_header(path)
    if header is None:
        raise ApiError(415, f"{label!r} is not an image: its content is not {FORMATS}, whatever its name says; "
                            "send the camera's image files")
    if header.size is None or min(header.size) < 1:
        raise ApiError(422, f"{label!r} is a {header.format} file whose header does not give its size "
                            "(truncated or damaged): send the camera's original file")
    check_pixels(header.size, repr(label), max_pixels)
    return header.size


def check_pixels(size: tuple[int, int], what: str, max_pixels: int) -> None:
    """ApiError 413 when an image of ``size`` (declared by a header, or an observations document's
    image_size) has more pixels than the limit: every later step allocates in proportion to them."""
    w, h = size
    if w * h > max_pixels:
        raise ApiError(413, f"{what} has {w}x{h} pixels, over the limit of {max_pixels} pixels per image "
                            "(the server's FREECAL_MAX_IMAGE_PIXELS): downscale the images")


def _jpeg_size(f: BinaryIO) -> tuple[int, int] | None:
    f.seek(2)
    while True:
        marker = f.read(2)
        if len(marker) < 2 or marker[0] != 0xFF:
            return None
        code = marker[1]
        while code == 0xFF:  # fill bytes before a marker
            byte = f.read(1)
            if not byte:
                return None
            code = byte[0]
        if code in (0xD8, 0x01) or 0xD0 <= code <= 0xD7:  # markers without a length
            continue
        length_bytes = f.read(2)
        if len(length_bytes) < 2:
            return None
        (length,) = struct.unpack(">H", length_bytes)
        if 0xC0 <= code <= 0xCF and code not in (0xC4, 0xC8, 0xCC):  # a start of frame (not DHT, JPG, DAC)
            data = f.read(5)
            if len(data) < 5:
                return None
            h, w = struct.unpack(">HH", data[1:5])
            return w, h
        if code == 0xDA or length < 2:  # scan data before any frame header: not a JPEG we bound
            return None
        f.seek(length - 2, 1)


def _bmp_size(head: bytes) -> tuple[int, int] | None:
    if len(head) < 26:
        return None
    (dib_size,) = struct.unpack("<I", head[14:18])
    if dib_size == 12:  # OS/2 BITMAPCOREHEADER: 16-bit sizes
        return struct.unpack("<HH", head[18:22])
    w, h = struct.unpack("<ii", head[18:26])
    return abs(w), abs(h)  # a negative height means top-down rows


TIFF_WIDTH, TIFF_HEIGHT, TIFF_TILE_WIDTH, TIFF_TILE_HEIGHT = 256, 257, 322, 323


def _tiff_size(f: BinaryIO, order: str) -> tuple[int, int] | None:
    """Of the first image (IFD0: the one OpenCV decodes). A tile larger than the image is
    allocated whole by OpenCV too, so the size returned covers the larger of the two."""
    f.seek(4)
    offset_bytes = f.read(4)
    if len(offset_bytes) < 4:
        return None
    f.seek(struct.unpack(order + "I", offset_bytes)[0])
    count_bytes = f.read(2)
    if len(count_bytes) < 2:
        return None
    (count,) = struct.unpack(order + "H", count_bytes)
    entries = f.read(12 * count)
    tags: dict[int, int] = {}
    for k in range(len(entries) // 12):
        tag, kind, n = struct.unpack(order + "HHI", entries[12 * k: 12 * k + 8])
        if tag in (TIFF_WIDTH, TIFF_HEIGHT, TIFF_TILE_WIDTH, TIFF_TILE_HEIGHT) and n == 1 and kind in (3, 4):
            value = entries[12 * k + 8: 12 * k + 12]
            tags[tag] = struct.unpack(order + "H", value[:2])[0] if kind == 3 else struct.unpack(order + "I", value)[0]
    if TIFF_WIDTH not in tags or TIFF_HEIGHT not in tags:
        return None
    return (max(tags[TIFF_WIDTH], tags.get(TIFF_TILE_WIDTH, 0)),
            max(tags[TIFF_HEIGHT], tags.get(TIFF_TILE_HEIGHT, 0)))


def _webp_size(head: bytes) -> tuple[int, int] | None:
    if len(head) < 30:
        return None
    chunk = head[12:16]
    if chunk == b"VP8 " and head[23:26] == b"\x9d\x01\x2a":  # lossy: 14-bit sizes after the start code
        w, h = struct.unpack("<HH", head[26:30])
        return w & 0x3FFF, h & 0x3FFF
    if chunk == b"VP8L" and head[20] == 0x2F:  # lossless: 14-bit sizes minus one, packed
        (bits,) = struct.unpack("<I", head[21:25])
        return (bits & 0x3FFF) + 1, ((bits >> 14) & 0x3FFF) + 1
    if chunk == b"VP8X":  # extended (alpha, animation): the canvas, 24-bit sizes minus one
        return (int.from_bytes(head[24:27], "little") + 1, int.from_bytes(head[27:30], "little") + 1)
    return None


def _pnm_size(f: BinaryIO) -> tuple[int, int] | None:
    """Width and height: the first two numbers after the magic, between whitespace and # comments."""
    f.seek(2)
    text = re.sub(rb"#[^\r\n]*", b" ", f.read(4096))
    numbers = re.match(rb"\s+(\d{1,9})\s+(\d{1,9})\s", text)
    return (int(numbers.group(1)), int(numbers.group(2))) if numbers else None

"""Turn a multipart upload into a set's files: many images, one zip of images,
or one observations JSON (corners already detected). Every limit a client can
hit answers 4xx naming the file and the limit."""
from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

from calib_core import Observations
from calib_core.detection.detect import IMAGE_SUFFIXES  # one list: what the command line and the service read

from ..base import storage
from ..base.settings import Settings
from . import bounded_json
from .errors import ApiError
from .image_header import check_decodable, check_pixels

MIN_SIDE = 32               # pixels: no board's corners fit in less
MAX_ZIP_RATIO = 200         # unpacked / packed bytes of a zip's images
CHUNK_SLACK = 1024 * 1024    # small zips of tiny images may compress better: no ratio check below this


@dataclass
class Upload:
    name: str
    stream: BinaryIO


@dataclass
class Received:
    kind: str                       # "images" | "observations"
    names: list[str]                # stored image names, in upload order
    observations: Observations | None = None


def receive(uploads: list[Upload], images_dir: Path, settings: Settings) -> Received:
    if not uploads:
        raise ApiError(422, "no files: send one or more images, one zip of images, or one observations JSON "
                            "in the multipart field 'files'")
    if len(uploads) == 1 and uploads[0].name.lower().endswith(".json"):
        return Received("observations", [], _observations(uploads[0], settings))
    if len(uploads) == 1 and uploads[0].name.lower().endswith(".zip"):
        return Received("images", _unzip(uploads[0], images_dir, settings))
    if len(uploads) > settings.max_files:
        raise ApiError(413, f"{len(uploads)} files is over the limit of {settings.max_files} per set")
    budget = settings.max_upload_bytes
    names: list[str] = []
    for up in uploads:
        name = _image_name(up.name, names)
        try:
            budget -= storage.copy_stream(up.stream, images_dir / name, budget)
        except storage.TooLarge:
            raise ApiError(413, f"the upload is over the limit of {settings.max_upload_bytes} bytes "
                                f"(reached at {up.name!r}): send fewer or smaller images") from None
        _check_image(images_dir / name, up.name, settings)
        names.append(name)
    return Received("images", names)


def _image_name(original: str, taken: list[str]) -> str:
    if not original.lower().endswith(IMAGE_SUFFIXES):
        raise ApiError(415, f"{original!r} is not an image this service reads "
                            f"({', '.join(IMAGE_SUFFIXES)}), a .zip of them, or one observations .json")
    name = storage.safe_name(original)
    stem, dot, ext = name.rpartition(".")
    k = 1
    while name in taken:  # the same base name from two folders of a zip
        k += 1
        name = f"{stem}_{k}{dot}{ext}"
    return name


def _check_image(path: Path, original: str, settings: Settings) -> None:
    """Refuse at upload what can never be a usable image: empty, not an image, too many pixels, too small."""
    if path.stat().st_size == 0:
        raise ApiError(422, f"{original!r} is empty (0 bytes): send the image file itself")
    w, h = check_decodable(path, original, settings.max_image_pixels)
    if min(w, h) < MIN_SIDE:
        raise ApiError(422, f"{original!r} is {w}x{h} pixels, too small to show a board (at least "
                            f"{MIN_SIDE} px a side): send the camera's full-resolution images")


def _unzip(up: Upload, images_dir: Path, settings: Settings) -> list[str]:
    tmp = settings.data_dir / "tmp" / f"upload-{images_dir.parent.name}.zip"
    try:
        storage.copy_stream(up.stream, tmp, settings.max_upload_bytes)
    except storage.TooLarge:
        raise ApiError(413, f"the zip is over the limit of {settings.max_upload_bytes} bytes") from None
    try:
        with zipfile.ZipFile(tmp) as zf:
            links = [m.filename for m in zf.infolist() if (m.external_attr >> 16) & 0o170000 == 0o120000]
            if links:  # never followed, never stored: a link names a file outside the upload
                raise ApiError(422, f"{up.name!r} holds a symbolic link ({links[0]!r}): zip the image files "
                                    "themselves (zip without -y / --symlinks)")
            unsafe = [m.filename for m in zf.infolist() if _escapes(m.filename)]
            if unsafe:  # never extracted as named (names are reduced to their base name), but refused: say why
                raise ApiError(422, f"{up.name!r} holds a path that leaves the archive ({unsafe[0]!r}): zip the "
                                    "images from inside their folder, with relative names")
            members = [m for m in zf.infolist() if not m.is_dir() and not _hidden(m.filename)
                       and m.filename.lower().endswith(IMAGE_SUFFIXES)]
            if not members:
                nested = any(m.filename.lower().endswith((".zip", ".tar", ".gz", ".7z", ".rar"))
                             for m in zf.infolist())
                raise ApiError(422, f"{up.name!r} holds no images ({', '.join(IMAGE_SUFFIXES)})"
                               + ("; archives inside it are not unpacked: put the images in one zip" if nested else ""))
            if len(members) > settings.max_files:
                raise ApiError(413, f"{up.name!r} holds {len(members)} images, over the limit of "
                                    f"{settings.max_files} per set")
            # declared sizes first (cheap), then actual bytes while extracting (a zip can lie)
            declared = sum(m.file_size for m in members)
            if declared > settings.max_upload_bytes:
                raise ApiError(413, f"{up.name!r} unpacks to more than {settings.max_upload_bytes} bytes")
            packed = max(1, sum(m.compress_size for m in members))
            if declared > MAX_ZIP_RATIO * packed + CHUNK_SLACK:
                # camera images barely compress (PNG, JPEG): this is a zip bomb or not images at all
                raise ApiError(413, f"{up.name!r} expands {declared / packed:.0f} times (images barely compress); "
                                    "zip the camera's image files as they are")
            budget, names = settings.max_upload_bytes, []
            for m in members:
                name = _image_name(m.filename, names)
                with zf.open(m) as src:
                    try:
                        budget -= storage.copy_stream(src, images_dir / name, budget)
                    except storage.TooLarge:
                        raise ApiError(413, f"{up.name!r} unpacks to more than {settings.max_upload_bytes} "
                                            "bytes") from None
                _check_image(images_dir / name, m.filename, settings)
                names.append(name)
            return names
    except (zipfile.BadZipFile, EOFError):
        raise ApiError(422, f"{up.name!r} is not a readable zip archive") from None
    finally:
        tmp.unlink(missing_ok=True)


def _escapes(path: str) -> bool:
    parts = path.replace("\\", "/").split("/")
    return path.startswith(("/", "\\")) or ".." in parts or (len(path) > 1 and path[1] == ":")


def _hidden(path: str) -> bool:
    return any(part.startswith(".") or part == "__MACOSX" for part in path.split("/"))


def _observations(up: Upload, settings: Settings) -> Observations:
    raw = up.stream.read(settings.max_observations_bytes + 1)
    if len(raw) > settings.max_observations_bytes:
        raise ApiError(413, f"{up.name!r} is over the limit of {settings.max_observations_bytes} bytes")
    try:
        doc = bounded_json.parse(raw, repr(up.name))
    except ApiError as exc:
        raise ApiError(exc.status, f"{exc.detail}; expected a freecal.observations/1 document") from None
    return observations_within(doc, repr(up.name), settings)


def observations_within(doc: Any, what: str, settings: Settings) -> Observations:
    """A freecal.observations/1 document (FormatError → 422 naming the field) whose image_size is
    within the pixel limit: undistortion maps and previews are made at that size. For an uploaded
    observations file and for a job's inline observations alike."""
    obs = Observations.from_json(doc)
    check_pixels(tuple(obs.image_size), f"the image_size of {what}", settings.max_image_pixels)
    return obs

"""Turn a multipart upload into a set's files: images (and zips of images), or one corners
file: a freecal observations JSON or mrcal's ``corners.vnl``.

A drop of many files keeps what it can use and lists what it skipped, with the reason in
the page's words (``Received.skipped``): a file of another kind (BabelCalib's ``.orpc``), an
unreadable or empty image, a zip's non-image members. Nothing usable at all answers 4xx
(the one file's own refusal when there was one file). Limits (count, bytes, pixels, zip
expansion) are refusals of the whole upload, as before: they name the file and the limit.
"""
from __future__ import annotations

import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

from calib_core import Observations
from calib_core.detection.detect import IMAGE_SUFFIXES  # one list: what the command line and the service read
from calib_core.detection.detect_image import MIN_SIDE  # one limit: an upload is skipped where detection would refuse

from ..base import storage
from ..base.settings import Settings
from . import bounded_json
from .errors import ApiError
from .image_header import check_decodable, check_pixels

MAX_ZIP_RATIO = 200         # unpacked / packed bytes of a zip's images
CHUNK_SLACK = 1024 * 1024    # small zips of tiny images may compress better: no ratio check below this
CORNER_SUFFIXES = (".json", ".vnl")   # corners found elsewhere: freecal observations, mrcal's corners.vnl
KINDS = "photos (JPEG, PNG, TIFF, BMP, WebP, PNM), a .zip of them, an observations .json or mrcal's corners.vnl"


@dataclass
class Upload:
    name: str
    stream: BinaryIO


@dataclass
class Received:
    kind: str                       # "images" | "observations"
    names: list[str]                # stored image names, in upload order
    observations: Observations | None = None
    skipped: list[dict[str, str]] = field(default_factory=list)   # {"name", "reason"}: files not used
    corners_file: Upload | None = None   # a corners.vnl, read by the caller once the board is known
    image_size: tuple[int, int] | None = None   # of the photos dropped with a corners.vnl


class _Skip(Exception):
    """This file cannot be used; the others can."""

    def __init__(self, error: ApiError):
        super().__init__(error.detail)
        self.error = error


def receive(uploads: list[Upload], images_dir: Path, settings: Settings) -> Received:
    if not uploads:
        raise ApiError(422, "no files: send one or more images, one zip of images, or one observations JSON "
                            "in the multipart field 'files'")
    if len(uploads) > settings.max_files:
        raise ApiError(413, f"{len(uploads)} files is over the limit of {settings.max_files} per set")
    corners = [u for u in uploads if u.name.lower().endswith(CORNER_SUFFIXES)]
    photos = [u for u in uploads if u.name.lower().endswith(IMAGE_SUFFIXES + (".zip",))]
    skipped: list[dict[str, str]] = []
    errors: list[ApiError] = []
    for u in uploads:
        if u not in corners and u not in photos:
            suffix = Path(u.name).suffix or "without a suffix"
            errors.append(ApiError(415, f"{u.name!r} is not an image this service reads ({', '.join(IMAGE_SUFFIXES)}), "
                                        "a .zip of them, or one observations .json"))
            skipped.append({"name": u.name, "reason": f"not a photo or a corners file ({suffix} files are not read; "
                                                      f"this page takes {KINDS})"})
    vnl = next((u for u in corners if u.name.lower().endswith(".vnl")), None)
    if vnl is not None:
        return _with_corners_vnl(vnl, photos, corners, skipped, images_dir, settings)
    if corners and not photos:
        chosen = corners[0]
        skipped += [{"name": u.name, "reason": "one corners file per set: upload the others as sets of their own"}
                    for u in corners[1:]]
        return Received("observations", [], _observations(chosen, settings), skipped)
    skipped += [{"name": u.name, "reason": "a corners file is a set of its own: upload it alone, not with photos"}
                for u in corners]
    names = _store_photos(photos, images_dir, settings, skipped, errors)
    if not names:
        if len(uploads) == 1 and errors:
            raise errors[0]   # one file: its own refusal, as it always was
        raise ApiError(422 if skipped else 415, "none of the files can be used: " + "; ".join(
            f"{s['name']}: {s['reason']}" for s in skipped[:5]) + (" …" if len(skipped) > 5 else ""))
    return Received("images", names, None, skipped)


def _store_photos(photos: list[Upload], images_dir: Path, settings: Settings, skipped: list[dict[str, str]],
                  errors: list[ApiError]) -> list[str]:
    """Store the images (and the images of zips); unreadable ones go to ``skipped``."""
    budget = settings.max_upload_bytes
    names: list[str] = []
    for up in photos:
        if up.name.lower().endswith(".zip"):
            got, budget = _unzip(up, images_dir, settings, names, budget, skipped, errors, alone=len(photos) == 1)
            names += got
            continue
        name = _image_name(up.name, names)
        try:
            budget -= storage.copy_stream(up.stream, images_dir / name, budget)
        except storage.TooLarge:
            raise ApiError(413, f"the upload is over the limit of {settings.max_upload_bytes} bytes "
                                f"(reached at {up.name!r}): send fewer or smaller images") from None
        try:
            _check_image(images_dir / name, up.name, settings)
        except _Skip as skip:
            (images_dir / name).unlink(missing_ok=True)
            errors.append(skip.error)
            skipped.append({"name": up.name, "reason": _reason(skip.error)})
            continue
        names.append(name)
    if len(names) > settings.max_files:
        raise ApiError(413, f"{len(names)} images is over the limit of {settings.max_files} per set")
    return names


def _reason(error: ApiError) -> str:
    """An image's refusal as a reason beside its name (the name is shown already)."""
    text = error.detail
    quote = text.find("' ")
    text = text[quote + 2:] if text.startswith("'") and quote > 0 else text
    return text[3:] if text.startswith("is ") else text   # "empty (0 bytes): ...", beside the name


def _with_corners_vnl(vnl: Upload, photos: list[Upload], corners: list[Upload], skipped: list[dict[str, str]],
                      images_dir: Path, settings: Settings) -> Received:
    """mrcal's corners.vnl: the photos dropped with it give the images' size (the file does not say it)."""
    skipped += [{"name": u.name, "reason": "one corners file per set: upload the others as sets of their own"}
                for u in corners if u is not vnl]
    size = None
    for up in photos:
        if up.name.lower().endswith(".zip"):
            skipped.append({"name": up.name, "reason": "not unpacked: the corners come from corners.vnl"})
            continue
        if size is None:
            probe = images_dir.parent / "size-probe"
            try:
                storage.copy_stream(up.stream, probe, settings.max_upload_bytes)
                size = check_decodable(probe, up.name, settings.max_image_pixels)
            except (storage.TooLarge, ApiError):
                size = None
            finally:
                probe.unlink(missing_ok=True)
        skipped.append({"name": up.name, "reason": "not searched for corners: they come from "
                                                   f"{vnl.name} (its photos give the image size)"})
    if size is None:
        raise ApiError(422, f"{vnl.name!r} does not say how large its photos are: drop one of them (or all) with it")
    return Received("observations", [], None, skipped, corners_file=vnl, image_size=size)
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
    """Skip at upload what can never be a usable image: empty, not an image, too many pixels, too small."""
    try:
        if path.stat().st_size == 0:
            raise ApiError(422, f"{original!r} is empty (0 bytes): send the image file itself")
        w, h = check_decodable(path, original, settings.max_image_pixels)
        if min(w, h) < MIN_SIDE:
            raise ApiError(422, f"{original!r} is {w}x{h} pixels, too small to show a board (at least "
                                f"{MIN_SIDE} px a side): send the camera's full-resolution images")
    except ApiError as exc:
        raise _Skip(exc) from None


def _unzip(up: Upload, images_dir: Path, settings: Settings, taken: list[str], budget: int,
           skipped: list[dict[str, str]], errors: list[ApiError], alone: bool) -> tuple[list[str], int]:
    """The zip's images stored (names, bytes budget left). Links, escaping paths and bombs refuse the
    upload; members that are no images, and images that cannot be read, are skipped."""
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
            files = [m for m in zf.infolist() if not m.is_dir() and not _hidden(m.filename)]
            members = [m for m in files if m.filename.lower().endswith(IMAGE_SUFFIXES)]
            if not members:
                nested = any(m.filename.lower().endswith((".zip", ".tar", ".gz", ".7z", ".rar")) for m in files)
                error = ApiError(422, f"{up.name!r} holds no images ({', '.join(IMAGE_SUFFIXES)})"
                                 + ("; archives inside it are not unpacked: put the images in one zip" if nested else ""))
                if alone:
                    raise error
                errors.append(error)
                skipped.append({"name": up.name, "reason": _reason(error)})
                return [], budget
            skipped += [{"name": f"{up.name}: {m.filename}", "reason": "not a photo (only the zip's images are read)"}
                        for m in files if m not in members]
            if len(taken) + len(members) > settings.max_files:
                raise ApiError(413, f"{up.name!r} holds {len(members)} images, over the limit of "
                                    f"{settings.max_files} per set")
            # declared sizes first (cheap), then actual bytes while extracting (a zip can lie)
            declared = sum(m.file_size for m in members)
            if declared > budget:
                raise ApiError(413, f"{up.name!r} unpacks to more than {settings.max_upload_bytes} bytes")
            packed = max(1, sum(m.compress_size for m in members))
            if declared > MAX_ZIP_RATIO * packed + CHUNK_SLACK:
                # camera images barely compress (PNG, JPEG): this is a zip bomb or not images at all
                raise ApiError(413, f"{up.name!r} expands {declared / packed:.0f} times (images barely compress); "
                                    "zip the camera's image files as they are")
            names: list[str] = []
            for m in members:
                name = _image_name(m.filename, taken + names)
                with zf.open(m) as src:
                    try:
                        budget -= storage.copy_stream(src, images_dir / name, budget)
                    except storage.TooLarge:
                        raise ApiError(413, f"{up.name!r} unpacks to more than {settings.max_upload_bytes} "
                                            "bytes") from None
                try:
                    _check_image(images_dir / name, m.filename, settings)
                except _Skip as skip:
                    (images_dir / name).unlink(missing_ok=True)
                    errors.append(skip.error)
                    skipped.append({"name": f"{up.name}: {m.filename}", "reason": _reason(skip.error)})
                    continue
                names.append(name)
            return names, budget
    except (zipfile.BadZipFile, EOFError):
        error = ApiError(422, f"{up.name!r} is not a readable zip archive")
        if alone:
            raise error from None
        errors.append(error)
        skipped.append({"name": up.name, "reason": "not a readable zip archive"})
        return [], budget
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
    check_pixels(obs.image_size, f"the image_size of {what}", settings.max_image_pixels)
    return obs

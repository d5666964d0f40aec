"""Every resource a request can ask for is bounded (issue 17, items 1-3, 5, 7, 9, 10):
image pixels in every format the service takes, bodies with or without a length,
inline observations and their image size, board specs, JSON nesting, settings'
ranges, and odd viewer paths. Each case is the issue's request over real HTTP
against `freecal serve`, answered 4xx with a message naming the limit and its
setting; never a 500, never a reset connection, never a file left behind.
"""
from __future__ import annotations

import io
import json
import os
import select
import socket
import struct
import subprocess
import sys
import threading
import time
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from ..conftest import synthetic
from .harness import FAST, QUICK, ROOT, Service, upload_observations, wait_job
from .test_hardening_inputs import BOARD, board_image, encode, png_header_only, refused, still_works

pytestmark = pytest.mark.slow

LIMIT_BYTES = 4 * 1024 * 1024
OBS_LIMIT = 24 * 1024 * 1024
PIXELS = 2_000_000     # the synthetic sets are 1024 x 1280 (1.3 MP)


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    root = tmp_path_factory.mktemp("bounds")
    env = {**FAST, "FREECAL_MAX_UPLOAD_BYTES": str(LIMIT_BYTES), "FREECAL_MAX_OBSERVATIONS_BYTES": str(OBS_LIMIT),
           "FREECAL_MAX_IMAGE_PIXELS": str(PIXELS), "FREECAL_MAX_FILES": "20", "FREECAL_VIEWER_PORT": "0"}
    svc = Service(root / "data", root, env).start()
    yield svc
    svc.stop()


def upload(svc: Service, name: str, data: bytes, board: str = BOARD):
    return svc.client.post("/api/sets", files=[("files", (name, data))], data={"board": board})


# ---- 1. every image format is checked from its header ----------------------------------------
def tiff_header(width: int, height: int, order: str = "<", tile: tuple[int, int] | None = None) -> bytes:
    """A TIFF whose first directory declares width x height (and a tile), and no pixels to speak of."""
    tags = [(256, 4, width), (257, 4, height), (258, 3, 8), (259, 3, 8), (262, 3, 1), (277, 3, 1)]
    if tile:
        tags += [(322, 4, tile[0]), (323, 4, tile[1])]
    ifd = struct.pack(order + "H", len(tags))
    for tag, kind, value in tags:
        packed = struct.pack(order + "H", value) + b"\0\0" if kind == 3 else struct.pack(order + "I", value)
        ifd += struct.pack(order + "HHI", tag, kind, 1) + packed
    magic = b"II*\x00" if order == "<" else b"MM\x00*"
    return magic + struct.pack(order + "I", 8) + ifd + b"\0\0\0\0" + zlib.compress(bytes(4096))


def webp(chunk: bytes, payload: bytes) -> bytes:
    body = b"WEBP" + chunk + struct.pack("<I", len(payload)) + payload
    return b"RIFF" + struct.pack("<I", len(body)) + body


def webp_lossy(w: int, h: int) -> bytes:
    return webp(b"VP8 ", b"\x10\x02\x00\x9d\x01\x2a" + struct.pack("<HH", w, h) + bytes(64))


def webp_lossless(w: int, h: int) -> bytes:
    return webp(b"VP8L", b"\x2f" + struct.pack("<I", (w - 1) | (h - 1) << 14) + bytes(64))


def webp_extended(w: int, h: int) -> bytes:
    return webp(b"VP8X", b"\0\0\0\0" + (w - 1).to_bytes(3, "little") + (h - 1).to_bytes(3, "little") + bytes(64))


def bmp_core(w: int, h: int) -> bytes:
    """An OS/2 bitmap: 16-bit sizes in a 12-byte header."""
    return b"BM" + struct.pack("<IHHI", 26 + 64, 0, 0, 26) + struct.pack("<IHHHH", 12, w, h, 1, 8) + bytes(64)


def deflate_tiff(w: int, h: int) -> bytes:
    """A real, small file: w x h of one grey, deflate-compressed (the issue's 1 MB for 20000 x 20000)."""
    ok, buf = cv2.imencode(".tiff", np.full((h, w), 128, np.uint8), [cv2.IMWRITE_TIFF_COMPRESSION, 8])
    assert ok
    return buf.tobytes()


BOMBS = {  # name: (file name, bytes, words in the answer); each declares more than PIXELS
    "deflate TIFF": ("big.tif", deflate_tiff(1500, 1400), ["1500x1400"]),
    "TIFF header, little-endian": ("bomb.tif", tiff_header(30000, 30000), ["30000x30000"]),
    "TIFF header, big-endian": ("bomb.tiff", tiff_header(30000, 30000, ">"), ["30000x30000"]),
    "TIFF with a tile larger than the image": ("tile.tif", tiff_header(320, 240, tile=(30000, 30000)),
                                              ["30000x30000"]),
    "PGM header": ("bomb.pgm", b"P5\n30000 30000\n255\n" + bytes(1024), ["30000x30000"]),
    "PPM header with a comment": ("bomb.ppm", b"P6\n# made by hand\n30000\t30000 255\n" + bytes(1024), ["30000x30000"]),
    "PBM header": ("bomb.pbm", b"P4 30000 30000\n" + bytes(1024), ["30000x30000"]),
    "ASCII PGM named .pnm": ("bomb.pnm", b"P2\n30000 30000\n255\n0 0 0\n", ["30000x30000"]),
    "WebP lossy": ("bomb.webp", webp_lossy(16383, 16383), ["16383x16383"]),
    "WebP lossless": ("bomb.webp", webp_lossless(16384, 16384), ["16384x16384"]),
    "WebP extended": ("bomb.webp", webp_extended(30000, 30000), ["30000x30000"]),
    "OS/2 BMP": ("bomb.bmp", bmp_core(30000, 30000), ["30000x30000"]),
    "PNG named .jpg": ("bomb.jpg", png_header_only(30000, 30000), ["30000x30000"]),
}


@pytest.mark.parametrize("case", list(BOMBS))
def test_images_declaring_too_many_pixels_are_refused_in_every_format(service, case):
    name, data, words = BOMBS[case]
    refused(service, upload(service, name, data), 413, *words, "FREECAL_MAX_IMAGE_PIXELS", "downscale")


def encoded(ext: str, img: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(ext, img)
    assert ok, ext
    return buf.tobytes()


UNBOUNDED = {  # formats OpenCV decodes but whose size the service does not read: refused, whatever the name
    "JPEG 2000 named .png": ("a.png", encoded(".jp2", board_image(0))),
    "Radiance HDR named .tif": ("a.tif", encoded(".hdr", board_image(0).astype(np.float32))),
    "Sun raster named .bmp": ("a.bmp", encoded(".sr", board_image(0))),
    "PAM named .pgm": ("a.pgm", encoded(".pam", board_image(0))),
    "BigTIFF": ("a.tif", b"II+\x00\x08\x00\x00\x00" + bytes(64)),
}


@pytest.mark.parametrize("case", list(UNBOUNDED))
def test_formats_whose_size_is_not_read_are_refused(service, case):
    name, data = UNBOUNDED[case]
    refused(service, upload(service, name, data), 415, "not an image", "PNG, JPEG, BMP, TIFF, WebP")


def test_a_header_without_its_size_is_refused(service):
    no_size = b"II*\x00" + struct.pack("<I", 8) + struct.pack("<H", 1) + struct.pack("<HHIHH", 258, 3, 1, 8, 0)
    refused(service, upload(service, "a.tif", no_size + bytes(64)), 422, "TIFF", "does not give its size")


FORMATS = {".png": encode(board_image(0)), ".tif": encoded(".tiff", board_image(1)),
           ".webp": encoded(".webp", board_image(2)), ".pgm": encoded(".pgm", board_image(3)),
           ".bmp": encoded(".bmp", board_image(4)), ".jpg": encoded(".jpg", board_image(5))}


def test_every_format_the_service_takes_uploads_and_previews(service):
    r = service.client.post("/api/sets", files=[("files", (f"v{ext}", data)) for ext, data in FORMATS.items()],
                            data={"board": BOARD})
    assert r.status_code == 201, r.text
    set_id = r.json()["id"]
    for image in r.json()["images"]:
        t = service.client.get(f"/api/sets/{set_id}/images/{image['name']}/thumbnail")
        assert t.status_code == 200 and t.content[:2] == b"\xff\xd8", (image["name"], t.text)


def test_the_api_never_decodes_more_than_the_limit(service):
    """An image stored before the limit was lowered (here: replaced on disk) is not decoded for its thumbnail."""
    r = upload(service, "small.png", encode(board_image(0)))
    assert r.status_code == 201, r.text
    set_id, name = r.json()["id"], r.json()["images"][0]["name"]
    big = encode(np.full((4000, 4000), 128, np.uint8))  # 16 MP: 48 MB decoded in colour
    (service.data_dir / "sets" / set_id / "images" / name).write_bytes(big)
    t = service.client.get(f"/api/sets/{set_id}/images/{name}/thumbnail", params={"size": 640})
    refused(service, t, 413, "4000x4000", "FREECAL_MAX_IMAGE_PIXELS")


def test_opencv_in_every_freecal_process_refuses_more_than_the_limit():
    """OpenCV reads its own limit once, as cv2 loads: freecal sets it first, from FREECAL_MAX_IMAGE_PIXELS."""
    code = ("import backend.cli, cv2, numpy as np\n"
            "ok, png = cv2.imencode('.png', np.zeros((1500, 1400), np.uint8))\n"
            "try:\n    print('decoded' if cv2.imdecode(png, 0) is not None else 'refused')\n"
            "except cv2.error:\n    print('refused')\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120,
                         env={**os.environ, "FREECAL_MAX_IMAGE_PIXELS": str(PIXELS)})
    assert out.stdout.strip() == "refused", out.stderr


def test_the_command_line_says_an_image_is_over_the_limit(tmp_path):
    image = tmp_path / "big.png"
    image.write_bytes(encode(np.zeros((1500, 1400), np.uint8)))
    out = subprocess.run([sys.executable, "-m", "backend.cli", "detect", str(image), "--board", BOARD,
                          "-o", str(tmp_path / "obs.json")], cwd=ROOT, capture_output=True, text=True, timeout=120,
                         env={**os.environ, "FREECAL_MAX_IMAGE_PIXELS": "1000000"})
    assert "more pixels than the limit of 1000000 (FREECAL_MAX_IMAGE_PIXELS)" in out.stdout, out.stdout + out.stderr
    assert "OpenCV(" not in out.stdout + out.stderr


# ---- 2. bodies without a length are counted as they arrive -----------------------------------------
def chunked_post(svc: Service, path: str, content_type: str, head: bytes, total: int, tail: bytes = b"",
                 pause_at: int | None = None, on_pause=None) -> tuple[int, bytes, int, float]:
    """POST ``head``, zeros up to ``total`` bytes and ``tail``, chunked, as fast as the server reads
    them; stop at its answer. Returns (status, body, bytes sent, seconds)."""
    sock = socket.create_connection(("127.0.0.1", svc.port), timeout=30)
    sock.sendall(f"POST {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: {content_type}\r\n"
                 "Transfer-Encoding: chunked\r\n\r\n".encode())
    sent, start, answer = 0, time.monotonic(), b""
    piece = bytes(64 * 1024)
    try:
        while sent < total:
            data = head if sent == 0 else piece
            sock.sendall(b"%x\r\n" % len(data) + data + b"\r\n")
            sent += len(data)
            if pause_at is not None and sent >= pause_at:
                on_pause()
                pause_at = None
            if select.select([sock], [], [], 0)[0]:
                break
        else:
            sock.sendall((b"%x\r\n" % len(tail) + tail + b"\r\n" if tail else b"") + b"0\r\n\r\n")
    except (BrokenPipeError, ConnectionResetError):
        pass  # the server answered and closed: read what it said
    seconds = time.monotonic() - start
    try:
        while b"\r\n\r\n" not in answer or len(answer.split(b"\r\n\r\n", 1)[1]) < _length(answer):
            more = sock.recv(65536)
            if not more:
                break
            answer += more
    except ConnectionResetError:
        pass
    finally:
        sock.close()
    assert answer, f"no answer: the connection was reset after {sent} bytes"
    status = int(answer.split(b" ", 2)[1])
    return status, answer.split(b"\r\n\r\n", 1)[1], sent, seconds


def _length(answer: bytes) -> int:
    for line in answer.split(b"\r\n\r\n", 1)[0].split(b"\r\n"):
        if line.lower().startswith(b"content-length:"):
            return int(line.split(b":")[1])
    return 0


def multipart_head(name: str = "big.png") -> tuple[str, bytes]:
    head = (f'--xyz\r\nContent-Disposition: form-data; name="board"\r\n\r\n{BOARD}\r\n--xyz\r\n'
            f'Content-Disposition: form-data; name="files"; filename="{name}"\r\n'
            "Content-Type: image/png\r\n\r\n").encode() + b"\x89PNG\r\n\x1a\n"
    return "multipart/form-data; boundary=xyz", head


def test_a_chunked_upload_stops_at_the_limit(service):
    before = service.client.get("/api/sets").json()["count"]
    content_type, head = multipart_head()
    status, body, sent, seconds = chunked_post(service, "/api/sets", content_type, head, 64 * LIMIT_BYTES)
    assert status == 413, body
    detail = json.loads(body)["detail"]
    assert "over the limit" in detail and "FREECAL_MAX_UPLOAD_BYTES" in detail
    assert sent < 4 * LIMIT_BYTES, f"the server read {sent} bytes before answering (limit {LIMIT_BYTES})"
    assert seconds < 10
    assert service.client.get("/api/sets").json()["count"] == before
    still_works(service)


def spool_files(pid: int) -> list[str]:
    """Where the process's open files are (deleted temp files included)."""
    found = []
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            found.append(os.readlink(fd))
        except OSError:
            pass
    return found


def test_an_upload_is_spooled_inside_the_data_directory(service):
    import tempfile

    content_type, head = multipart_head()
    seen: list[str] = []

    def look() -> None:
        time.sleep(0.5)  # the server has read what was sent
        seen.extend(spool_files(service.proc.pid))

    status, body, _, _ = chunked_post(service, "/api/sets", content_type, head, 3 * 1024 * 1024,
                                      tail=b"\r\n--xyz--\r\n", pause_at=2 * 1024 * 1024, on_pause=look)
    assert status == 422 and b"does not give its size" in body, body  # zeros are no image: the spool is the point
    system_tmp, inside = tempfile.gettempdir() + "/", str(service.data_dir)
    assert not [p for p in seen if p.startswith(system_tmp) and "(deleted)" in p and not p.startswith(inside)], seen
    assert [p for p in seen if p.startswith(str(service.data_dir / "tmp"))], \
        f"no spool file in the data directory: {seen}"
    still_works(service)


# ---- 3. inline observations: bounded, parsed off the event loop, their image size bounded ---------------
def obs_doc() -> dict:
    return synthetic("radial").train.to_json()


def test_a_job_body_over_the_observations_limit_is_refused_before_parsing(service):
    body = b'{"observations": {"views": [' + b"1," * (OBS_LIMIT // 2 + 2**20) + b'1]}}'
    r = service.client.post("/api/jobs", content=body, headers={"content-type": "application/json"})
    refused(service, r, 413, "over the limit", "FREECAL_MAX_OBSERVATIONS_BYTES")
    status, answer, sent, _ = chunked_post(service, "/api/jobs", "application/json", b'{"observations": [',
                                           4 * OBS_LIMIT)
    assert status == 413 and b"FREECAL_MAX_OBSERVATIONS_BYTES" in answer, answer
    assert sent < 2 * OBS_LIMIT


def test_health_stays_fast_while_a_large_job_body_is_parsed(service):
    doc = obs_doc()
    views = doc["views"]
    doc["views"] = [{**views[i % len(views)], "name": f"v{i}"} for i in range(1800)]  # ~22 MB
    body = json.dumps({"observations": doc, "method": "no-such-method"}).encode()
    assert len(body) < OBS_LIMIT
    answers, latencies = [], []

    def post() -> None:
        answers.append(service.client.post("/api/jobs", content=body, headers={"content-type": "application/json"}))

    poster = threading.Thread(target=post)
    poster.start()
    while poster.is_alive():
        t = time.monotonic()
        assert service.client.get("/api/health").status_code == 200
        latencies.append(time.monotonic() - t)
        time.sleep(0.02)
    poster.join()
    refused(service, answers[0], 422, "unknown method")
    # Parsed on the event loop, the body held health for 5 s; a 2-core machine running the rest of the suite
    # alone costs a few hundred ms (measured: median 0.29 s, worst 0.68 s), so the bounds are loose.
    assert np.median(latencies) < 0.6 and max(latencies) < 2.0, \
        f"/api/health took {np.median(latencies):.2f} s (median), up to {max(latencies):.2f} s, while the body was parsed"


def test_image_size_over_the_pixel_limit_is_refused(service):
    doc = {**obs_doc(), "image_size": [9600, 7200]}
    r = service.client.post("/api/jobs", json={"observations": doc, "settings": QUICK, "method": "bspline"})
    refused(service, r, 413, "image_size", "9600x7200", "FREECAL_MAX_IMAGE_PIXELS")
    r = service.client.post("/api/sets", files={"files": ("obs.json", json.dumps(doc), "application/json")})
    refused(service, r, 413, "image_size", "9600x7200", "FREECAL_MAX_IMAGE_PIXELS")


def test_maps_are_computed_once_and_kept_as_a_result_file(service):
    r = service.client.post("/api/jobs", json={"observations": obs_doc(), "method": "bspline", "settings": QUICK})
    assert r.status_code == 201, r.text
    job = wait_job(service.client, r.json()["id"], 90, service.logs())
    assert job["state"] == "done", job
    first = service.client.get(f"/api/jobs/{job['id']}/maps.npz")
    assert first.status_code == 200, first.text
    kept = service.data_dir / "jobs" / job["id"] / "maps.npz"
    assert kept.is_file()
    made = kept.stat().st_mtime_ns
    again = service.client.get(f"/api/jobs/{job['id']}/maps.npz")
    assert again.content == first.content and kept.stat().st_mtime_ns == made
    assert 'filename="freecal-job-' in again.headers["content-disposition"]
    with np.load(io.BytesIO(again.content)) as maps:
        assert maps["map_x"].ndim == 2 and maps["map_x"].shape == maps["map_y"].shape


# ---- 5. board specs are bounded --------------------------------------------------------------------------
BOARDS = {
    "chessboard of a million corners": ("chessboard:1000000x3:25mm", ["1000000x3", "at most 100x100"]),
    "ChArUco of a million squares": ("charuco:1000x1000:40mm:20mm:DICT_6X6_250", ["at most 100x100"]),
    "ChArUco with more markers than its dictionary": ("charuco:40x40:40mm:20mm:DICT_6X6_250",
                                                      ["800 markers", "DICT_6X6_250 holds (250)"]),
    "a 23-digit square size": ("chessboard:9x6:" + "1" * 23 + "mm", ["square size", "from 0.001 mm to 10 m"]),
    "a grid of 30 digits": ("chessboard:" + "9" * 30 + "x6:25mm", ["at most 100x100"]),
    "a board object of a million columns": (json.dumps({"type": "chessboard", "cols": 10**6, "rows": 6,
                                                        "square_size": 25}), ["at most 100x100"]),
}


@pytest.mark.parametrize("case", list(BOARDS))
def test_board_specs_are_bounded(service, case):
    spec, words = BOARDS[case]
    refused(service, upload(service, "a.png", encode(board_image(0)), board=spec), 422, *words)


# ---- 7. nesting is bounded before any walk -----------------------------------------------------------------
def nested(depth: int) -> str:
    return "[" * depth + "]" * depth


@pytest.mark.parametrize("depth", [33, 500, 900, 100_000])
def test_deeply_nested_settings_are_refused(service, depth):
    body = f'{{"set_id": "x", "method": "bspline", "settings": {{"intervals": {nested(depth)}}}}}'
    r = service.client.post("/api/jobs", content=body, headers={"content-type": "application/json"})
    refused(service, r, 422, "more than 32 levels deep")


def test_deeply_nested_uploads_are_refused(service):
    r = service.client.post("/api/sets", files={"files": ("obs.json", f'{{"views": {nested(900)}}}')})
    refused(service, r, 422, "more than 32 levels deep", "freecal.observations/1")
    board = f'{{"type": "chessboard", "cols": {nested(900)}}}'
    refused(service, upload(service, "a.png", encode(board_image(0)), board=board), 422, "more than 32 levels deep")
    r = service.client.post("/api/viewer", content=f'{{"job_id": {nested(900)}}}',
                            headers={"content-type": "application/json"})
    refused(service, r, 422, "more than 32 levels deep")


# ---- 9. every setting's range is checked at submission -----------------------------------------------------
SETTINGS = {  # (method, settings, words)
    "the issue's intervals": ("bspline", {"intervals": [1000000, 1000000]}, ["intervals", "from 1 to 50", "1000000"]),
    "max_intervals": ("bspline", {"max_intervals": 10**6}, ["max_intervals", "from 1 to 50"]),
    "max_iterations": ("bspline", {"max_iterations": 10**9}, ["max_iterations", "from 1 to 10000"]),
    "lambda_smooth": ("bspline", {"lambda_smooth": 1e300}, ["lambda_smooth", "at most 1e+06"]),
    "time_budget": ("bspline", {"time_budget": 1e12}, ["time_budget", "at most 86400"]),
    "interior knots": ("bspline", {"knots": "explicit", "interior_knots": [list(range(500)), [1.0]]},
                       ["interior_knots", "at most 49"]),
    "TPS centres": ("tps", {"max_centers": 10**7}, ["max_centers", "from 10 to 2000"]),
    "TPS smoothing grid": ("tps", {"smoothing": [1e-3] * 1000}, ["smoothing", "1 to 20 numbers"]),
    "MLS folds": ("mls", {"folds": 10**6}, ["folds", "from 2 to 20"]),
    "fisheye coefficients": ("fisheye", {"n_coefficients": 100}, ["n_coefficients", "from 1 to 8"]),
    "auto's decision views": ("auto", {"decision_views": 10**6}, ["decision_views", "from 3 to 1000"]),
    "outlier_sigma": ("zhang", {"outlier_sigma": 1e9}, ["outlier_sigma", "at most 100"]),
    "compare's splits": ("compare", {"splits": 10**6}, ["splits", "from 2 to 20"]),
}


@pytest.fixture(scope="module")
def ready_set(service):
    return upload_observations(service.client, obs_doc())


@pytest.mark.parametrize("case", list(SETTINGS))
def test_settings_out_of_range_are_refused_naming_the_range(service, ready_set, case):
    method, settings, words = SETTINGS[case]
    r = service.client.post("/api/jobs", json={"set_id": ready_set, "method": method, "settings": settings})
    refused(service, r, 422, *words)


# ---- 10. viewer paths that are no URL ---------------------------------------------------------------------
@pytest.mark.parametrize("path", ["/viewer/a%20b", "/viewer/%0d%0aX:%20y", "/viewer/%ff%fe", "/viewer/a%00b"])
def test_odd_viewer_paths_answer_4xx(service, path):
    assert service.client.get("/api/viewer").json()["enabled"], "this test needs the 3D view"
    r = service.client.get(path)
    assert r.status_code in (400, 404), (r.status_code, r.text)
    still_works(service)

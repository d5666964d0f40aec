"""Bad input over the API: each case gets a 4xx whose message says what to do, or a
failed job / rejected image with the reason; never a 500, never a dead worker,
never a file left half-written or outside its set. After every case the
service still answers (``still_works``); the last test runs a good job.

One `freecal serve` (API + a real worker) serves the whole module: the cases
are independent requests, so isolation costs nothing and the module stays fast.
"""
from __future__ import annotations

import io
import json
import struct
import zipfile
import zlib

import cv2
import numpy as np
import pytest

from ..conftest import synthetic
from .harness import FAST, QUICK, Service, create_job, upload_observations, wait_for, wait_job

pytestmark = pytest.mark.slow

BOARD = "chessboard:6x4:20mm"         # what board_png draws: 7x5 squares, 6x4 inner corners
LIMIT_BYTES = 4 * 1024 * 1024


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    root = tmp_path_factory.mktemp("hardening")
    env = {**FAST, "FREECAL_MAX_UPLOAD_BYTES": str(LIMIT_BYTES), "FREECAL_MAX_FILES": "20",
           "FREECAL_MAX_IMAGE_PIXELS": "2000000", "FREECAL_VIEWER": "0"}
    svc = Service(root / "data", root, env).start()
    yield svc
    svc.stop()


# ---- inputs ------------------------------------------------------------------------------
def board_image(k: int = 0, size: tuple[int, int] = (320, 240)) -> np.ndarray:
    """A chessboard seen in perspective (a different tilt per k), 8-bit grey."""
    w, h = size
    sq = 24
    board = np.full((7 * sq, 9 * sq), 255, np.uint8)
    for r in range(5):
        for c in range(7):
            if (r + c) % 2 == 0:
                board[sq + r * sq: sq + (r + 1) * sq, sq + c * sq: sq + (c + 1) * sq] = 0
    bh, bw = board.shape
    m = 0.12 * w
    dst = np.float32([[m, m], [w - m, m], [w - m, h - m], [m, h - m]])
    dst += np.random.default_rng(k).uniform(-0.08 * w, 0.08 * w, (4, 2)).astype(np.float32)
    H = cv2.getPerspectiveTransform(np.float32([[0, 0], [bw, 0], [bw, bh], [0, bh]]), dst)
    return cv2.GaussianBlur(cv2.warpPerspective(board, H, (w, h), borderValue=200), (3, 3), 0.7)


def encode(img: np.ndarray, ext: str = ".png") -> bytes:
    ok, buf = cv2.imencode(ext, img)
    assert ok
    return buf.tobytes()


def png_header_only(width: int, height: int) -> bytes:
    """A decompression bomb's face: a valid PNG signature and IHDR claiming width x height."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    chunk = b"IHDR" + ihdr
    return b"\x89PNG\r\n\x1a\n" + struct.pack(">I", len(ihdr)) + chunk + struct.pack(">I", zlib.crc32(chunk))


def jpeg_header_only(width: int, height: int) -> bytes:
    sof = b"\xff\xc0" + struct.pack(">HBHHB", 11, 8, height, width, 1) + b"\x01\x11\x00"
    return b"\xff\xd8\xff\xe0" + struct.pack(">H", 16) + b"JFIF\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00" + sof


def zip_bytes(entries: list[tuple[str, bytes]], symlink: tuple[str, str] | None = None) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in entries:
            zf.writestr(name, data)
        if symlink:
            info = zipfile.ZipInfo(symlink[0])
            info.external_attr = (0o120777 << 16)  # S_IFLNK: what `zip -y` stores
            zf.writestr(info, symlink[1])
    return buf.getvalue()


GOOD = encode(board_image(0))


# ---- checks --------------------------------------------------------------------------------
def still_works(svc: Service) -> None:
    """The service answers, and no upload left a temp file or a stray file anywhere."""
    assert svc.client.get("/api/health").status_code == 200
    assert svc.client.get("/api/sets").status_code == 200
    data = svc.data_dir
    leftovers = [p for p in data.rglob(".tmp-*")] + [p for p in (data / "tmp").iterdir()]
    assert not leftovers, f"half-written files left behind: {leftovers}"


def refused(svc: Service, r, status: int, *words: str) -> None:
    assert r.status_code == status, r.text
    detail = r.json()["detail"]
    for w in words:
        assert w in detail, f"{w!r} not in {detail!r}"
    assert "Traceback" not in detail
    still_works(svc)


def post_files(svc: Service, files, board: str | None = BOARD):
    return svc.client.post("/api/sets", files=files, data={} if board is None else {"board": board})


# ---- uploads answered at once --------------------------------------------------------------
UPLOAD_CASES = {
    "empty file": ([("files", ("a.png", b""))], BOARD, 422, ["empty", "send the image"]),
    "text named .png": ([("files", ("a.png", b"hello, not an image"))], BOARD, 415, ["not an image", "send"]),
    "pdf named .jpg": ([("files", ("a.jpg", b"%PDF-1.4 ..."))], BOARD, 415, ["not an image"]),
    "not an image suffix": ([("files", ("notes.txt", b"hi"))], BOARD, 415, ["not an image this service reads"]),
    "1x1 image": ([("files", ("dot.png", encode(np.zeros((1, 1), np.uint8))))], BOARD, 422,
                  ["1x1", "full-resolution"]),
    "png decompression bomb": ([("files", ("bomb.png", png_header_only(100_000, 100_000)))], BOARD, 413,
                               ["100000x100000", "downscale"]),
    "jpeg decompression bomb": ([("files", ("bomb.jpg", jpeg_header_only(60_000, 60_000)))], BOARD, 413,
                                ["60000x60000", "downscale"]),
    "too many files": ([("files", (f"{i}.png", GOOD)) for i in range(21)], BOARD, 413, ["21 files", "limit of 20"]),
    "file over the size limit": ([("files", ("big.png", b"\x89PNG\r\n\x1a\n" + bytes(LIMIT_BYTES)))], BOARD, 413,
                                 ["limit", "fewer or smaller"]),
    "images without a board": ([("files", ("a.png", GOOD))], None, 422, ["board spec", "chessboard:9x6:25mm"]),
    "board spec malformed": ([("files", ("a.png", GOOD))], "chessboard:nine", 422, ["chessboard:9x6"]),
    "board of unknown type": ([("files", ("a.png", GOOD))], "hexboard:9x6:25mm", 422, ["chessboard"]),
    "board square size negative": ([("files", ("a.png", GOOD))], "chessboard:9x6:-25mm", 422, ["length like 25mm"]),
    "board JSON malformed": ([("files", ("a.png", GOOD))], "{not json", 422, ["chessboard:9x6:25mm"]),
    "zip not a zip": ([("files", ("set.zip", b"PK\x03\x04 not really"))], BOARD, 422, ["not a readable zip"]),
    "zip with no images": ([("files", ("set.zip", zip_bytes([("readme.txt", b"hi")])))], BOARD, 422,
                           ["holds no images"]),
    "nested zip": ([("files", ("set.zip", zip_bytes([("inner.zip", zip_bytes([("a.png", GOOD)]))])))], BOARD, 422,
                   ["not unpacked", "one zip"]),
    "zip with a symlink": ([("files", ("set.zip", zip_bytes([("a.png", GOOD)], symlink=("b.png", "/etc/passwd"))))],
                           BOARD, 422, ["symbolic link", "zip the image files"]),
    "zip bomb (expansion ratio)": ([("files", ("set.zip", zip_bytes([("a.png", b"\x89PNG\r\n\x1a\n" + bytes(3 * 2**20))])))],
                                   BOARD, 413, ["expands", "times"]),
    "zip unpacking past the limit": ([("files", ("set.zip", zip_bytes([(f"{i}.png", bytes(2**20)) for i in range(5)])))],
                                     BOARD, 413, ["unpacks to more than"]),
    "zip holding too many images": ([("files", ("set.zip", zip_bytes([(f"{i}.png", GOOD) for i in range(21)])))],
                                    BOARD, 413, ["21 images", "limit of 20"]),
    "zip member not an image": ([("files", ("set.zip", zip_bytes([("a.png", b"plain text")])))], BOARD, 415,
                                ["not an image"]),
}


@pytest.mark.parametrize("case", list(UPLOAD_CASES))
def test_bad_upload_is_refused_with_advice(service, case):
    files, board, status, words = UPLOAD_CASES[case]
    before = service.client.get("/api/sets").json()["count"]
    refused(service, post_files(service, files, board), status, *words)
    assert service.client.get("/api/sets").json()["count"] == before, "a refused upload must store nothing"


def test_no_files_field(service):
    refused(service, service.client.post("/api/sets", data={"board": BOARD}), 422, "files", "/docs")


def test_request_body_over_the_limit_is_refused_before_reading(service):
    r = service.client.post("/api/sets", content=b"x" * (LIMIT_BYTES + 2 * 2**20),
                            headers={"content-type": "multipart/form-data; boundary=x"})
    refused(service, r, 413, "FREECAL_MAX_UPLOAD_BYTES", "fewer or smaller")


# ---- observations JSON uploads --------------------------------------------------------------
def obs_doc() -> dict:
    return synthetic("radial").train.to_json()


def with_(doc: dict, fn) -> dict:
    fn(doc)
    return doc


JSON_CASES = {
    "not JSON": (b"{not json", ["not valid JSON", "freecal.observations/1"]),
    "top-level array": (b"[1, 2]", ["JSON object"]),
    "wrong format": (json.dumps({**obs_doc(), "format": "opencv/1"}).encode(), ["format", "freecal.observations/1"]),
    "NaN in a point": (json.dumps(with_(obs_doc(), lambda d: d["views"][0]["image_points"][0].__setitem__(0, float("nan"))))
                       .encode(), ["not finite"]),
    "Infinity in a point": (json.dumps(with_(obs_doc(), lambda d: d["views"][1]["object_points"][3].__setitem__(1, float("inf"))))
                            .encode(), ["not finite"]),
    "wildly wrong pixel": (json.dumps(with_(obs_doc(), lambda d: d["views"][0]["image_points"].__setitem__(2, [4e12, 1.0])))
                           .encode(), ["far outside", "image_size"]),
    "integer past float64": (json.dumps(obs_doc()).replace('"image_size": [', '"image_size": [1' + "0" * 400 + ", ", 1)
                             .encode(), ["image_size"]),
    "negative image size": (json.dumps({**obs_doc(), "image_size": [-640, 480]}).encode(), ["image_size", "positive"]),
    "duplicate view names": (json.dumps(with_(obs_doc(), lambda d: d["views"][1].__setitem__("name", d["views"][0]["name"])))
                             .encode(), ["appears twice", "unique"]),
    "points that do not pair up": (json.dumps(with_(obs_doc(), lambda d: d["views"][0]["image_points"].pop())).encode(),
                                   ["pair up"]),
    "no views": (json.dumps({**obs_doc(), "views": []}).encode(), ["views", "non-empty"]),
}


@pytest.mark.parametrize("case", list(JSON_CASES))
def test_bad_observations_json_is_refused_with_advice(service, case):
    body, words = JSON_CASES[case]
    r = service.client.post("/api/sets", files={"files": ("obs.json", body, "application/json")})
    refused(service, r, 422, *words)


# ---- jobs: settings refused at once ------------------------------------------------------
@pytest.fixture(scope="module")
def ready_set(service):
    return upload_observations(service.client, obs_doc())


SETTINGS_CASES = {
    "negative lambda": ({"lambda_smooth": -1}, ["lambda_smooth", "at least 0"]),
    "zero intervals": ({"intervals": [0, 0]}, ["intervals", "from 1 to 50"]),
    "zero iterations": ({"max_iterations": 0}, ["max_iterations", "from 1 to"]),
    "negative outlier sigma": ({"outlier_sigma": -2}, ["outlier_sigma", "at least 0"]),
    "unknown setting": ({"no_such": 1}, ["unknown setting"]),
    "wrong type": ({"intervals": "many"}, ["intervals"]),
    "unknown knot strategy": ({"knots": "magic"}, ["knots", "uniform"]),
}


@pytest.mark.parametrize("case", list(SETTINGS_CASES))
def test_bad_settings_are_refused_with_advice(service, ready_set, case):
    settings, words = SETTINGS_CASES[case]
    r = service.client.post("/api/jobs", json={"set_id": ready_set, "method": "bspline", "settings": settings})
    refused(service, r, 422, *words)


def test_nan_setting_is_refused(service, ready_set):
    # httpx refuses to send NaN; a hostile client writes it by hand (Python's parser reads it)
    body = f'{{"set_id": "{ready_set}", "settings": {{"lambda_smooth": NaN}}}}'
    r = service.client.post("/api/jobs", content=body, headers={"content-type": "application/json"})
    refused(service, r, 422, "settings.lambda_smooth", "finite")


def test_unknown_method_and_missing_set(service, ready_set):
    refused(service, service.client.post("/api/jobs", json={"set_id": ready_set, "method": "magic"}), 422,
            "unknown method", "available")
    refused(service, service.client.post("/api/jobs", json={"set_id": "nope"}), 404, "no set", "/api/sets")
    refused(service, service.client.post("/api/jobs", json={"set_id": ready_set, "method": "compare",
                                                           "settings": {"splits": 1}}), 422, "splits", "from 2 to")


# ---- jobs that fail in the worker, with the reason -------------------------------------------
def failed_with(svc: Service, job_id: str, *words: str) -> None:
    job = wait_job(svc.client, job_id, 90, svc.logs())
    assert job["state"] == "failed", job
    for w in words:
        assert w in job["error"], job["error"]
    assert not job["downloads"], "a failed job offers no (half-written) results"
    still_works(svc)


def test_too_few_views(service):
    doc = obs_doc()
    doc["views"] = doc["views"][:2]
    r = service.client.post("/api/jobs", json={"observations": doc, "method": "bspline", "settings": QUICK})
    failed_with(service, r.json()["id"], "at least 3 views")


def test_too_few_corners_for_the_knot_grid(service):
    # The paper's model asked for: the field alone must carry the corners. (With method "auto" a
    # field they cannot carry drops out of the model choice: tests/core/test_bspline_method.py.)
    doc = obs_doc()
    doc["views"] = doc["views"][:3]
    r = service.client.post("/api/jobs", json={"observations": doc, "method": "bspline",
                                               "settings": {**QUICK, "intervals": [30, 30], "core": "none"}})
    failed_with(service, r.json()["id"], "equations for", "fewer knot intervals")


def fronto_parallel_views() -> dict:
    """Every view face-on: the focal length and the distance trade off exactly (degenerate)."""
    K = np.array([[800.0, 0, 320], [0, 800, 240], [0, 0, 1]])
    obj = np.array([[x * 25.0, y * 25.0, 0] for y in range(6) for x in range(9)])
    views = []
    for k, t in enumerate([(-100, -60, 500), (-50, -80, 600), (-120, -40, 450), (-80, -70, 700), (-60, -50, 550)]):
        img, _ = cv2.projectPoints(obj, np.zeros(3), np.array(t, float), K, None)
        img = img.reshape(-1, 2) + np.random.default_rng(k).normal(0, 0.2, (len(obj), 2))
        views.append({"name": f"v{k}", "object_points": obj.tolist(), "image_points": img.tolist()})
    return {"format": "freecal.observations/1", "image_size": [640, 480], "views": views}


def test_all_views_fronto_parallel(service):
    r = service.client.post("/api/jobs", json={"observations": fronto_parallel_views(), "method": "bspline", "settings": QUICK})
    failed_with(service, r.json()["id"], "fronto-parallel", "tilted")


# ---- image sets: each image gets a verdict with its reason --------------------------------
def truncated(data: bytes) -> bytes:
    return data[: len(data) // 3]


def corrupt_jpeg() -> bytes:
    data = bytearray(encode(board_image(9), ".jpg"))
    data[200:] = np.random.default_rng(1).integers(0, 255, len(data) - 200, dtype=np.uint8).tobytes()
    return bytes(data)


IMAGES = {  # name: (bytes, expected status, words in the reason)
    "good0.png": (encode(board_image(0)), "used", []),
    "good1.png": (encode(board_image(1)), "used", []),
    "good2.jpg": (encode(board_image(2), ".jpg"), "used", []),
    "good3.png": (encode(board_image(3)), "used", []),
    "sixteen_bit.png": (encode(board_image(4).astype(np.uint16) * 257), "used", []),
    "rgba.png": (encode(cv2.cvtColor(board_image(5), cv2.COLOR_GRAY2BGRA)), "used", []),
    "truncated.png": (truncated(encode(board_image(6))), "rejected", []),
    "truncated.jpg": (truncated(encode(board_image(7), ".jpg")), "rejected", []),
    "corrupt.jpg": (corrupt_jpeg(), "rejected", []),
    "no_board.png": (encode(np.full((240, 320), 128, np.uint8)), "rejected", ["not found"]),
    "larger.png": (encode(board_image(8, (640, 480))), "rejected", ["differ"]),
}


@pytest.fixture(scope="module")
def image_set(service):
    r = post_files(service, [("files", (n, data)) for n, (data, _, _) in IMAGES.items()])
    assert r.status_code == 201, r.text
    set_id = r.json()["id"]
    s = wait_for(lambda: (s := service.client.get(f"/api/sets/{set_id}").json())["state"] in ("ready", "failed") and s,
                 120, "detection of the mixed set", service.logs())
    assert s["state"] == "ready", s["error"]
    return s


@pytest.mark.parametrize("name", list(IMAGES))
def test_each_image_gets_a_verdict_with_its_reason(service, image_set, name):
    _, status, words = IMAGES[name]
    report = {im["name"]: im for im in image_set["images"]}[name]
    assert report["status"] == status, report
    if status == "rejected":
        assert report["reason"], "a rejected image must say why"
        for w in words:
            assert w in report["reason"], report
    still_works(service)


def test_the_set_keeps_one_camera_and_the_usable_views(service, image_set):
    used = [im["name"] for im in image_set["images"] if im["status"] == "used"]
    assert image_set["image_size"] == [320, 240] and image_set["n_views"] == len(used) >= 6
    assert image_set["coverage"]["fraction_covered"] > 0


def test_board_that_does_not_match_the_photos(service):
    files = [("files", (f"{k}.png", encode(board_image(k)))) for k in range(3)]
    r = post_files(service, files, "charuco:5x7:40mm:20mm:DICT_6X6_250")
    assert r.status_code == 201, r.text
    set_id = r.json()["id"]
    s = wait_for(lambda: (s := service.client.get(f"/api/sets/{set_id}").json())["state"] in ("ready", "failed") and s,
                 60, "detection with the wrong board", service.logs())
    assert s["state"] == "failed" and "found in none of the 3 photos" in s["error"] and "check the board" in s["error"]
    assert all(im["status"] == "rejected" and "board not found" in im["reason"] for im in s["images"])
    refused(service, service.client.post("/api/jobs", json={"set_id": set_id}), 409, "failed", "board")


def test_a_set_of_photos_that_cannot_be_read_says_so_not_check_the_board(service):
    """A truncated JPEG (the upload sniffs its header; decoding fails later): the set's reason read
    "the chessboard of 9 × 6 inner corners was found in none of the 1 photos: check the board's size"."""
    whole = encode(board_image(0), ".jpg")
    r = post_files(service, [("files", ("cut.jpg", whole[: len(whole) // 3]))], "chessboard:9x6:25mm")
    assert r.status_code == 201, r.text
    set_id = r.json()["id"]
    s = wait_for(lambda: (s := service.client.get(f"/api/sets/{set_id}").json())["state"] in ("ready", "failed") and s,
                 60, "detection of an unreadable photo", service.logs())
    assert s["state"] == "failed" and "could not be read as images" in s["error"] and "board's size" not in s["error"]


ODD_NAMES = ["../../escape.png", "/etc/absolute.png", "C:\\Windows\\win.png", "spaces & ümlauts (1).png",
             ".hidden.png", "x" * 300 + ".png", "%2e%2e%2fenc.png", "semi;colon'quote\".png"]


def test_odd_file_names_are_stored_under_safe_names_inside_the_set(service):
    r = post_files(service, [("files", (n, GOOD)) for n in ODD_NAMES])
    assert r.status_code == 201, r.text
    body = r.json()
    folder = service.data_dir / "sets" / body["id"] / "images"
    stored = [im["name"] for im in body["images"]]
    assert len(stored) == len(ODD_NAMES) == len(set(stored))
    for name in stored:
        assert "/" not in name and "\\" not in name and not name.startswith(".") and len(name) <= 200, name
        assert (folder / name).is_file() and (folder / name).resolve().parent == folder.resolve()
    assert sorted(p.name for p in folder.iterdir()) == sorted(stored)  # nothing written anywhere else
    # the thumbnail endpoint takes the stored name (URL-quoted), never a path
    assert service.client.get(f"/api/sets/{body['id']}/images/{stored[3]}/thumbnail").status_code in (200, 404)
    still_works(service)


@pytest.mark.parametrize("path", ["../../../outside.png", "/abs/olute.png", "dir/../../x.png", "C:\\up\\c.png"])
def test_zip_paths_that_leave_the_archive_are_refused(service, path):
    data = zip_bytes([("ok.png", GOOD), (path, GOOD)])
    refused(service, post_files(service, [("files", ("set.zip", data))]), 422, "leaves the archive", "relative names")
    assert not list(service.data_dir.parent.glob("*.png")) and not list(service.data_dir.glob("*.png"))


def test_zip_folders_are_flattened_inside_the_set(service):
    data = zip_bytes([("left/a.png", GOOD), ("right/a.png", GOOD), ("deep/er/b.png", GOOD)])
    r = post_files(service, [("files", ("set.zip", data))])
    assert r.status_code == 201, r.text
    assert [im["name"] for im in r.json()["images"]] == ["a.png", "a_2.png", "b.png"]
    folder = service.data_dir / "sets" / r.json()["id"] / "images"
    assert sorted(p.name for p in folder.iterdir()) == ["a.png", "a_2.png", "b.png"]
    still_works(service)


def test_service_still_calibrates_after_all_of_the_above(service):
    assert service.proc.alive()
    health = service.client.get("/api/health").json()
    assert health["workers"] >= 1, "the worker must have survived every bad input"
    job = wait_job(service.client, create_job(service.client, upload_observations(service.client, obs_doc()),
                                              settings=QUICK), 60, service.logs())
    assert job["state"] == "done", job["error"]

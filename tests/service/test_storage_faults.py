"""A full and a read-only data directory under the real server: reads keep working (listings,
health, thumbnails, downloads of finished results), writes answer 507/503 in words, health says
"degraded" with the condition, and once the disk is writable again the service is healthy by itself.

Real conditions, without touching the machine: the server runs in a mount namespace of its own
(``unshare -m``) with its data directory on a small tmpfs. Full: the test fills that tmpfs (through
``/proc/PID/root``) until it says ENOSPC. Read-only: a read-only bind mount is put over the data
directory in the server's namespace (``nsenter``), so every file opened from then on is on a
read-only file system (EROFS), as after a remount; removing it makes the directory writable again.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pytest

from ..conftest import synthetic
from .harness import FAST, QUICK, Proc, Service, create_job, free_port, upload_observations, wait_for, wait_job
from .test_hardening_inputs import GOOD

pytestmark = pytest.mark.slow

OBS = synthetic("radial").train.to_json()


def namespaces_work() -> bool:
    if not (shutil.which("unshare") and shutil.which("nsenter")):
        return False
    probe = subprocess.run(["unshare", "-m", "sh", "-c", "mount -t tmpfs -o size=1m tmpfs /mnt"],
                           capture_output=True)
    return probe.returncode == 0


needs_namespaces = pytest.mark.skipif(not namespaces_work(),
                                      reason="needs unshare/nsenter and mount rights (root, or a user namespace)")


class TmpfsService(Service):
    """`freecal serve` in its own mount namespace, its data directory a tmpfs of ``size``."""

    size = "32m"

    def start(self) -> TmpfsService:
        self.port = free_port()
        self.starts += 1
        self.data_dir.mkdir(parents=True, exist_ok=True)
        serve = " ".join([sys.executable, "-m", "backend.cli", "serve", "--port", str(self.port), "--data-dir",
                          str(self.data_dir), "--workers", "1"])
        script = f"mount -t tmpfs -o size={self.size} tmpfs {self.data_dir} && exec {serve}"
        self.proc = Proc(f"serve-{self.starts}", ["unshare", "-m", "sh", "-c", script], self.log_dir, self.env)
        import httpx

        self.client = httpx.Client(base_url=f"http://127.0.0.1:{self.port}", timeout=30)
        wait_for(lambda: self.client.get("/api/health").status_code == 200, 60, "the API to answer", [self.proc])
        return self

    def inside(self, *command: str) -> None:
        subprocess.run(["nsenter", "-t", str(self.proc.pid), "-m", *command], check=True, capture_output=True)

    @property
    def seen_data_dir(self):
        """The data directory as the server sees it (its tmpfs), from outside its namespace."""
        return f"/proc/{self.proc.pid}/root{self.data_dir}"


def fill(svc: TmpfsService) -> None:
    with open(f"{svc.seen_data_dir}/filler", "wb") as f:
        try:
            while True:
                f.write(b"\0" * (1 << 20))
        except OSError as exc:
            assert exc.errno == 28, exc  # ENOSPC: full


def make_read_only(svc: TmpfsService) -> None:
    # Made read-only beside the data directory, then moved over it: remounting in place races the
    # server, whose files opened for writing in between make the kernel refuse (EBUSY).
    d, staging = str(svc.data_dir), svc.log_dir / "read-only"
    staging.mkdir(exist_ok=True)
    svc.inside("sh", "-c", f"mount --bind {d} {staging} && mount -o remount,bind,ro {staging} "
                           f"&& mount --move {staging} {d}")


CONDITIONS = {  # name: (make it, undo it, status of a write, words of the write's answer, words in health)
    "full": (fill, lambda svc: os.unlink(f"{svc.seen_data_dir}/filler"), 507,
             ["disk is full", "nothing was stored", "free space"], ["is full", "free space", "Reads and downloads work"]),
    "read-only": (make_read_only, lambda svc: svc.inside("umount", "--lazy", str(svc.data_dir)), 503,
                  ["cannot write its data directory", "nothing was stored"],
                  ["cannot be written", "Read-only file system", "Reads and downloads work"]),
}


@needs_namespaces
@pytest.mark.parametrize("condition", sorted(CONDITIONS))
def test_reads_work_and_writes_say_why_on_a_full_or_read_only_disk(tmp_path, condition):
    make, undo, status, write_words, health_words = CONDITIONS[condition]
    svc = TmpfsService(tmp_path / "data", tmp_path, {**FAST, "FREECAL_VIEWER": "0"}).start()
    try:
        c = svc.client
        set_id = upload_observations(c, OBS)
        job = wait_job(c, create_job(c, set_id, settings=QUICK), 60, svc.logs())
        assert job["state"] == "done", job["error"]
        r = c.post("/api/sets", data={"board": "chessboard:6x4:20mm"},
                   files=[("files", (f"{k}.png", GOOD)) for k in range(3)])
        images = r.json()["id"]
        wait_for(lambda: c.get(f"/api/sets/{images}").json()["state"] == "ready", 60, "detection", svc.logs())
        thumb = f"/api/sets/{images}/images/0.png/thumbnail"
        assert c.get(thumb).status_code == 200  # cached from now on
        result = c.get(f"/api/jobs/{job['id']}/calibration.json").content

        make(svc)
        health = c.get("/api/health").json()
        assert health["status"] == "degraded" and not health["storage_writable"], health
        assert all(w in health["problems"][0] for w in health_words), health
        reads = ["/api/sets", f"/api/sets/{set_id}", f"/api/sets/{images}", "/api/jobs", f"/api/jobs/{job['id']}",
                 f"/api/jobs/{job['id']}/heatmap.json", f"/api/sets/{images}/observations.json", thumb,
                 thumb + "?size=640",  # never made before: made, served, not kept
                 "/api/methods", "/"]
        for path in reads:
            assert c.get(path).status_code == 200, (path, c.get(path).text)
        assert c.get(f"/api/jobs/{job['id']}/calibration.json").content == result
        for r in (c.post("/api/sets", files={"files": ("more.json", json.dumps(OBS))}),
                  c.post("/api/jobs", json={"set_id": set_id, "method": "bspline", "settings": QUICK})):
            assert r.status_code == status, r.text
            assert all(w in r.json()["detail"] for w in write_words), r.json()
        assert c.get("/api/health").status_code == 200  # still answering after the refused writes

        undo(svc)
        wait_for(lambda: c.get("/api/health").json()["status"] == "ok", 60, "health to be ok again", svc.logs())
        again = wait_job(c, create_job(c, set_id, settings=QUICK), 60, svc.logs())
        assert again["state"] == "done", again["error"]
        sets = c.get("/api/sets").json()["sets"]
        assert {s["id"] for s in sets} == {set_id, images}, "a refused upload must leave nothing behind"
    finally:
        svc.stop()

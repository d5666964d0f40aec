"""Real processes for the service tests: the API (`freecal serve`), workers
(`freecal worker`) and a Redis server, each on a free loopback port, with
bounded waits that fail saying what was awaited and what the logs said.

(Helpers only: pytest collects no tests here.)
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import pytest

ROOT = Path(__file__).resolve().parents[2]

# Fast leases so a killed worker is noticed in seconds, not a minute.
FAST = {"FREECAL_HEARTBEAT_SECONDS": "0.3", "FREECAL_LEASE_SECONDS": "2.5", "FREECAL_POLL_SECONDS": "0.2"}

# A quick calibration (< 1 s) and a slower one (several seconds, progress to watch).
QUICK = {"knots": "uniform", "intervals": [4, 4], "max_iterations": 10, "lambda_smooth": 0.1}
SLOW = {"knots": "uniform", "intervals": [10, 10], "max_iterations": 60, "lambda_smooth": 0.1, "ftol": 1e-15,
        "outlier_sigma": 0}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for(check: Callable[[], Any], timeout: float, what: str, logs: list[Proc] = (), every: float = 0.1) -> Any:
    """Poll ``check`` until it returns something truthy; fail naming ``what`` (with log tails)."""
    deadline = time.monotonic() + timeout
    last_error = None
    while time.monotonic() < deadline:
        try:
            value = check()
            if value:
                return value
        except (httpx.HTTPError, OSError) as exc:
            last_error = exc
        time.sleep(every)
    tails = "\n".join(p.tail() for p in logs)
    pytest.fail(f"timed out after {timeout:g} s waiting for {what} (last error: {last_error})\n{tails}")


class Proc:
    """A child process with its output in a log file; stopped (and reaped) on ``stop``."""

    def __init__(self, name: str, argv: list[str], log_dir: Path, env: dict[str, str] | None = None):
        self.name = name
        self.log_path = log_dir / f"{name}.log"
        self.log = open(self.log_path, "ab")
        self.proc = subprocess.Popen(argv, cwd=ROOT, stdout=self.log, stderr=subprocess.STDOUT,
                                     env={**os.environ, **(env or {})}, start_new_session=True)

    @property
    def pid(self) -> int:
        return self.proc.pid

    def alive(self) -> bool:
        return self.proc.poll() is None

    def tail(self, n: int = 30) -> str:
        try:
            lines = self.log_path.read_text(errors="replace").splitlines()[-n:]
        except OSError:
            lines = []
        return f"--- {self.name} (last {len(lines)} lines) ---\n" + "\n".join(lines)

    def kill(self) -> None:
        """SIGKILL the whole process group: a crash, no chance to clean up."""
        if self.alive():
            os.killpg(self.proc.pid, signal.SIGKILL)
        self.proc.wait(timeout=10)

    def stop(self, timeout: float = 10) -> None:
        if self.alive():
            try:
                os.killpg(self.proc.pid, signal.SIGTERM)
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout=10)
            except ProcessLookupError:
                pass
        self.log.close()


def freecal(*args: str) -> list[str]:
    return [sys.executable, "-m", "backend.cli", *args]


class Service:
    """``freecal serve`` on a free port over ``data_dir``; restartable on the same data."""

    def __init__(self, data_dir: Path, log_dir: Path, env: dict[str, str], workers: int = 1):
        self.data_dir, self.log_dir, self.env, self.workers = data_dir, log_dir, env, workers
        self.proc: Proc | None = None
        self.starts = 0

    def start(self) -> Service:
        self.port = free_port()
        self.starts += 1
        self.proc = Proc(f"serve-{self.starts}", freecal("serve", "--port", str(self.port), "--data-dir",
                                                        str(self.data_dir), "--workers", str(self.workers)),
                         self.log_dir, self.env)
        # a server started with FREECAL_TOKEN: the test's own client sends it
        token = {"Authorization": f"Bearer {self.env['FREECAL_TOKEN']}"} if self.env.get("FREECAL_TOKEN") else {}
        self.client = httpx.Client(base_url=f"http://127.0.0.1:{self.port}", timeout=30, headers=token)
        wait_for(lambda: self.client.get("/api/health").status_code == 200, 60, "the API to answer /api/health",
                 [self.proc])
        return self

    def stop(self) -> None:
        if self.proc is not None:
            self.client.close()
            self.proc.stop()

    def restart(self) -> Service:
        self.stop()
        return self.start()

    def logs(self) -> list[Proc]:
        return [self.proc] if self.proc else []


def start_worker(data_dir: Path, log_dir: Path, env: dict[str, str], name: str) -> Proc:
    return Proc(name, freecal("worker", "--data-dir", str(data_dir)), log_dir, env)


class RedisServer:
    def __init__(self, log_dir: Path):
        exe = shutil.which("redis-server")
        if exe is None:
            pytest.skip("redis-server is not installed (`make test` installs it via apt-get as root)")
        self.port = free_port()
        # no persistence: the queue only needs to live as long as the test
        self.proc = Proc("redis", [exe, "--port", str(self.port), "--bind", "127.0.0.1", "--save", "",
                                   "--appendonly", "no", "--dir", str(log_dir)], log_dir)
        wait_for(self._ping, 20, "redis-server to answer PING", [self.proc])

    @property
    def url(self) -> str:
        return f"redis://127.0.0.1:{self.port}/0"

    def _ping(self) -> bool:
        with socket.create_connection(("127.0.0.1", self.port), timeout=1) as s:
            s.sendall(b"PING\r\n")
            return s.recv(16).startswith(b"+PONG")

    def stop(self) -> None:
        self.proc.stop()


# ---- API steps ---------------------------------------------------------------------
def upload_observations(client: httpx.Client, obs_json: dict) -> str:
    r = client.post("/api/sets", files={"files": ("train.json", json.dumps(obs_json), "application/json")})
    assert r.status_code == 201, r.text
    assert r.json()["state"] == "ready"
    return r.json()["id"]


def create_job(client: httpx.Client, set_id: str, method: str = "bspline", settings: dict | None = None) -> str:
    r = client.post("/api/jobs", json={"set_id": set_id, "method": method, "settings": settings or {}})
    assert r.status_code == 201, r.text
    return r.json()["id"]


def wait_job(client: httpx.Client, job_id: str, timeout: float, logs: list[Proc],
             states: tuple[str, ...] = ("done", "failed", "cancelled"), seen: list | None = None) -> dict:
    """Poll the job until it reaches one of ``states``; every status read goes to ``seen``."""
    def check():
        job = client.get(f"/api/jobs/{job_id}").json()
        if seen is not None:
            seen.append(job)
        return job if job["state"] in states else None

    return wait_for(check, timeout, f"job {job_id} to reach {'/'.join(states)}", logs, every=0.05)

"""Service throughput and status-read latency, over real HTTP with real workers.

    python -m benchmarks service [--jobs 12] [--workers 1,2] [--queue sqlite|redis] [--readers 4] [--rate 40]

For each worker count: a fresh data directory, ``freecal serve --workers 0``
plus N ``freecal worker`` processes, the same synthetic sets
(``calib_core.synth.generate``, one per lens of the paper) and the same job settings;
reports jobs per minute from the first submission to the last completion.
Meanwhile ``--readers`` clients poll ``GET /api/jobs/{id}`` at ``--rate``
requests per second in all (a bounded load: it must not starve the workers of
CPU, one request in flight per reader) and their latencies are reported as
percentiles.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import httpx

from calib_core import synth

ROOT = Path(__file__).resolve().parents[1]
SETTINGS = {"knots": "uniform", "intervals": [8, 8], "max_iterations": 40, "lambda_smooth": 0.1}
FAST = {"FREECAL_HEARTBEAT_SECONDS": "1", "FREECAL_LEASE_SECONDS": "10", "FREECAL_POLL_SECONDS": "0.2"}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def spawn(args: list[str], env: dict[str, str], log: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "backend.cli", *args], cwd=ROOT, env={**os.environ, **env},
                            stdout=open(log, "ab"), stderr=subprocess.STDOUT, start_new_session=True)


def stop(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGTERM)
    for p in procs:
        try:
            p.wait(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()


def wait(check, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            if check():
                return
        except httpx.HTTPError:
            pass
        time.sleep(0.1)
    raise SystemExit(f"timed out waiting for {what}")


def run_once(n_workers: int, n_jobs: int, readers: int, rate: float, env: dict[str, str], work: Path) -> dict:
    data = work / f"data-{n_workers}"
    port = free_port()
    procs = [spawn(["serve", "--port", str(port), "--data-dir", str(data), "--workers", "0"], env,
                   work / f"serve-{n_workers}.log")]
    try:
        client = httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=60)
        wait(lambda: client.get("/api/health").status_code == 200, 60, "the API")
        procs += [spawn(["worker", "--data-dir", str(data)], env, work / f"worker-{n_workers}-{k}.log")
                  for k in range(n_workers)]
        wait(lambda: client.get("/api/health").json()["workers"] == n_workers, 60, f"{n_workers} workers")
        set_ids = []
        for kind in synth.PAPER_KINDS:
            doc = synth.generate(kind, 0.3, 0).train.to_json()
            r = client.post("/api/sets", files={"files": (f"{kind}.json", json.dumps(doc), "application/json")})
            set_ids.append(r.json()["id"])

        t0 = time.perf_counter()
        ids = [client.post("/api/jobs", json={"set_id": set_ids[k % len(set_ids)], "settings": SETTINGS}).json()["id"]
               for k in range(n_jobs)]
        stop_reading = threading.Event()
        latencies: list[float] = []
        lock = threading.Lock()

        def reader(k: int) -> None:
            c = httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=30)
            i, period = k, readers / rate
            next_at = time.perf_counter()
            while not stop_reading.is_set():
                t = time.perf_counter()
                c.get(f"/api/jobs/{ids[i % len(ids)]}").raise_for_status()
                with lock:
                    latencies.append(time.perf_counter() - t)
                i += 1
                next_at += period
                stop_reading.wait(max(0.0, next_at - time.perf_counter()))
            c.close()

        threads = [threading.Thread(target=reader, args=(k,), daemon=True) for k in range(readers)]
        for t in threads:
            t.start()

        def all_done() -> bool:
            states = [client.get(f"/api/jobs/{i}").json()["state"] for i in ids]
            if "failed" in states:
                raise SystemExit("a job failed; see the logs in " + str(work))
            return all(s == "done" for s in states)

        wait(all_done, 1800, "the jobs")
        seconds = time.perf_counter() - t0
        stop_reading.set()
        for t in threads:
            t.join()
        lat = sorted(latencies)
        pct = lambda q: 1000 * lat[min(len(lat) - 1, int(q * len(lat)))] if lat else float("nan")  # noqa: E731
        return {"workers": n_workers, "jobs": n_jobs, "seconds": seconds, "jobs_per_min": 60 * n_jobs / seconds,
                "reads": len(lat), "reads_per_s": len(lat) / seconds, "p50_ms": pct(0.5), "p95_ms": pct(0.95),
                "p99_ms": pct(0.99), "mean_ms": 1000 * statistics.fmean(lat) if lat else float("nan")}
    finally:
        stop(procs)


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks service", description=__doc__.splitlines()[0])
    p.add_argument("--jobs", type=int, default=12)
    p.add_argument("--workers", default="1,2", help="worker counts to compare, e.g. 1,2,4")
    p.add_argument("--readers", type=int, default=4, help="concurrent status readers (one request in flight each)")
    p.add_argument("--rate", type=float, default=40.0, help="status reads per second, all readers together")
    p.add_argument("--blas-threads", type=int, default=1, help="BLAS threads per worker (FREECAL_BLAS_THREADS)")
    p.add_argument("--queue", choices=("sqlite", "redis"), default="sqlite")
    args = p.parse_args(argv)

    from backend.commands.output import table

    work = Path(tempfile.mkdtemp(prefix="freecal-bench-"))
    env = {**FAST, "FREECAL_QUEUE": args.queue, "FREECAL_BLAS_THREADS": str(args.blas_threads)}
    redis = None
    try:
        if args.queue == "redis":
            exe = shutil.which("redis-server") or sys.exit("redis-server is not installed")
            rport = free_port()
            redis = subprocess.Popen([exe, "--port", str(rport), "--bind", "127.0.0.1", "--save", "",
                                      "--appendonly", "no"], stdout=subprocess.DEVNULL, start_new_session=True)
            env["FREECAL_REDIS_URL"] = f"redis://127.0.0.1:{rport}/0"
            time.sleep(0.5)
        rows = []
        for n in [int(x) for x in args.workers.split(",")]:
            r = run_once(n, args.jobs, args.readers, args.rate, env, work)
            rows.append((r["workers"], r["jobs"], r["seconds"], r["jobs_per_min"], r["reads_per_s"],
                         r["p50_ms"], r["p95_ms"], r["p99_ms"]))
        print(f"freecal service on the {args.queue} queue: {args.jobs} bspline jobs "
              f"(uniform 8x8 knots, synthetic {', '.join(synth.PAPER_KINDS)}), {args.readers} status readers "
              f"at {args.rate:g} reads/s, {args.blas_threads} BLAS thread(s) per worker, "
              f"{os.cpu_count()} cores\n")
        table(["workers", "jobs", "time [s]", "jobs/min", "status reads/s", "p50 [ms]", "p95 [ms]", "p99 [ms]"], rows)
    finally:
        if redis is not None:
            stop([redis])
        shutil.rmtree(work, ignore_errors=True)
    return 0

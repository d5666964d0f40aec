"""Bounded load on loopback: many clients reading job status while uploads and jobs run.

    python -m benchmarks load [--clients 100] [--reads 5000] [--uploads 10] [--time-cap 120] [--workers 1]

Starts ``freecal serve`` (API + ``--workers`` worker processes) on a fresh data
directory and a free loopback port, then, at once:

- ``--clients`` concurrent clients (one httpx async client, one connection
  each) poll ``GET /api/jobs/{id}`` every ``--interval`` seconds, as the page
  does while a job runs, until ``--reads`` reads are done in all or
  ``--time-cap`` seconds have passed (back-to-back reads would measure only
  queueing: with N requests always in flight, latency = N / throughput);
- one writer uploads ``--uploads`` observation sets, each followed by a
  calibration job (quick settings), so the worker runs jobs throughout.

Reports read latency (p50/p90/p99/max), reads per second, errors (any non-2xx
or failed request), write latency and how many jobs finished; the target is
read p99 < 200 ms with zero errors (exit status 1 when missed). The load is
bounded (fixed counts, a time cap) so it can run on a shared machine.
"""
from __future__ import annotations

import argparse
import asyncio
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx

from calib_core import synth

ROOT = Path(__file__).resolve().parents[1]
QUICK = {"knots": "uniform", "intervals": [4, 4], "max_iterations": 10, "lambda_smooth": 0.1}
TARGET_P99_MS = 200.0


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def percentile(values: list[float], q: float) -> float:
    if not values:
        return float("nan")
    s = sorted(values)
    return s[min(len(s) - 1, int(round(q / 100 * (len(s) - 1))))]


async def run_load(base: str, args, obs_text: str) -> dict:
    limits = httpx.Limits(max_connections=args.clients + 4, max_keepalive_connections=args.clients + 4)
    async with httpx.AsyncClient(base_url=base, timeout=30, limits=limits) as c:
        r = await c.post("/api/sets", files={"files": ("seed.json", obs_text)})
        r.raise_for_status()
        seed_set = r.json()["id"]
        r = await c.post("/api/jobs", json={"set_id": seed_set, "settings": QUICK})
        r.raise_for_status()
        target = r.json()["id"]

        reads: list[float] = []
        errors: list[str] = []
        writes: list[float] = []
        job_ids: list[str] = []
        remaining = [args.reads]
        deadline = time.monotonic() + args.time_cap

        async def reader(k: int) -> None:
            await asyncio.sleep(args.interval * k / args.clients)  # spread the clients over one interval
            while remaining[0] > 0 and time.monotonic() < deadline:
                next_at = time.monotonic() + args.interval
                remaining[0] -= 1
                t0 = time.perf_counter()
                try:
                    r = await c.get(f"/api/jobs/{target}")
                    if r.status_code != 200:
                        errors.append(f"read {r.status_code}: {r.text[:100]}")
                except httpx.HTTPError as exc:
                    errors.append(f"read {type(exc).__name__}: {exc}")
                reads.append(time.perf_counter() - t0)
                await asyncio.sleep(max(0.0, next_at - time.monotonic()))

        async def writer() -> None:
            for k in range(args.uploads):
                if time.monotonic() > deadline:
                    return
                for request in ("set", "job"):
                    t0 = time.perf_counter()
                    try:
                        if request == "set":
                            r = await c.post("/api/sets", files={"files": (f"load-{k}.json", obs_text)})
                            set_id = r.json().get("id") if r.status_code == 201 else None
                        else:
                            r = await c.post("/api/jobs", json={"set_id": set_id, "settings": QUICK})
                            if r.status_code == 201:
                                job_ids.append(r.json()["id"])
                        if r.status_code != 201:
                            errors.append(f"{request} {r.status_code}: {r.text[:100]}")
                    except httpx.HTTPError as exc:
                        errors.append(f"{request} {type(exc).__name__}: {exc}")
                    writes.append(time.perf_counter() - t0)
                await asyncio.sleep(0.2)

        t0 = time.perf_counter()
        await asyncio.gather(writer(), *(reader(k) for k in range(args.clients)))
        wall = time.perf_counter() - t0

        # let the queued jobs finish (bounded), then count them
        end = time.monotonic() + args.time_cap
        states: dict[str, int] = {}
        while args.workers > 0 and time.monotonic() < end:
            jobs = (await c.get("/api/jobs")).json()["jobs"]
            states = {}
            for j in jobs:
                states[j["state"]] = states.get(j["state"], 0) + 1
            if not states.get("queued") and not states.get("running"):
                break
            await asyncio.sleep(0.5)
    return {"reads": reads, "errors": errors, "writes": writes, "wall": wall, "states": states,
            "jobs_created": len(job_ids) + 1}


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks load", description=__doc__.splitlines()[0])
    p.add_argument("--clients", type=int, default=100)
    p.add_argument("--reads", type=int, default=3000, help="status reads in all")
    p.add_argument("--interval", type=float, default=1.0, help="seconds between one client's reads")
    p.add_argument("--uploads", type=int, default=10, help="observation sets uploaded, one job each")
    p.add_argument("--time-cap", type=float, default=120.0, help="seconds for the load (and again for the jobs)")
    p.add_argument("--workers", type=int, default=1)
    args = p.parse_args(argv)

    obs_text = json.dumps(synth.generate("radial", 0.3, 0).train.to_json())
    with tempfile.TemporaryDirectory(prefix="freecal-load-") as tmp:
        port = free_port()
        env = {**os.environ, "FREECAL_VIEWER": "0", "FREECAL_MAX_JOBS_PER_CLIENT": "100000",
               "OPENBLAS_NUM_THREADS": "1"}
        log = open(Path(tmp) / "serve.log", "ab")
        proc = subprocess.Popen([sys.executable, "-m", "backend.cli", "serve", "--port", str(port), "--data-dir",
                                 str(Path(tmp) / "data"), "--workers", str(args.workers)], cwd=ROOT, env=env,
                                stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        base = f"http://127.0.0.1:{port}"
        try:
            for _ in range(600):
                try:
                    if httpx.get(base + "/api/health", timeout=1).status_code == 200:
                        break
                except httpx.HTTPError:
                    pass
                time.sleep(0.1)
            else:
                print("the server did not start; its log:\n" + (Path(tmp) / "serve.log").read_text())
                return 1
            out = asyncio.run(run_load(base, args, obs_text))
        finally:
            os.killpg(proc.pid, signal.SIGTERM)
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)

    ms = [1000 * x for x in out["reads"]]
    wms = [1000 * x for x in out["writes"]]
    p99 = percentile(ms, 99)
    print(f"load: {args.clients} clients reading job status every {args.interval:g} s, {args.uploads} uploads + jobs, "
          f"{args.workers} worker(s), loopback")
    print(f"  reads   {len(ms)} in {out['wall']:.1f} s ({len(ms) / out['wall']:.0f}/s): "
          f"p50 {percentile(ms, 50):.1f} ms, p90 {percentile(ms, 90):.1f} ms, p99 {p99:.1f} ms, "
          f"max {max(ms, default=float('nan')):.1f} ms")
    print(f"  writes  {len(wms)}: p50 {percentile(wms, 50):.1f} ms, max {max(wms, default=float('nan')):.1f} ms")
    print(f"  jobs    {out['jobs_created']} created, by state at the end: {out['states']}")
    print(f"  errors  {len(out['errors'])}" + "".join(f"\n    {e}" for e in out["errors"][:10]))
    ok = p99 < TARGET_P99_MS and not out["errors"]
    print(f"  target  read p99 < {TARGET_P99_MS:.0f} ms with zero errors: {'met' if ok else 'MISSED'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

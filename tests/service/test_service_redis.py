"""The same flow on the distributed queue: a real redis-server (started here on a
free loopback port), the API without embedded workers, and two worker processes
sharing the jobs."""
from __future__ import annotations

import pytest

from calib_core import Calibration

from ..conftest import synthetic
from .harness import (
    FAST,
    QUICK,
    RedisServer,
    Service,
    create_job,
    start_worker,
    upload_observations,
    wait_for,
    wait_job,
)

pytestmark = pytest.mark.slow


def test_two_workers_share_jobs_on_redis(tmp_path):
    redis = RedisServer(tmp_path)
    env = {**FAST, "FREECAL_QUEUE": "redis", "FREECAL_REDIS_URL": redis.url}
    svc = Service(tmp_path / "data", tmp_path, env, workers=0)
    workers = []
    try:
        svc.start()
        workers = [start_worker(svc.data_dir, tmp_path, env, f"worker-{k}") for k in (1, 2)]
        logs = svc.logs() + workers + [redis.proc]
        wait_for(lambda: svc.client.get("/api/health").json()["workers"] == 2, 60, "two live workers", logs)
        assert svc.client.get("/api/health").json()["queue"] == "redis"

        set_id = upload_observations(svc.client, synthetic("radial").train.to_json())
        # a slower job than QUICK so one worker is busy while the other takes the next
        settings = {**QUICK, "intervals": [8, 8], "max_iterations": 40}
        ids = [create_job(svc.client, set_id, settings=settings) for _ in range(6)]
        jobs = [wait_job(svc.client, i, 120, logs) for i in ids]
        assert all(j["state"] == "done" for j in jobs), [j["error"] for j in jobs]
        assert len({j["worker"] for j in jobs}) == 2, "both workers should have run jobs"

        before = svc.client.get(f"/api/jobs/{ids[0]}/calibration.json")
        Calibration.from_json(before.json())
        svc.restart()
        assert svc.client.get(f"/api/jobs/{ids[0]}").json()["state"] == "done"
        assert svc.client.get(f"/api/jobs/{ids[0]}/calibration.json").content == before.content
    finally:
        for w in workers:
            w.stop()
        svc.stop()
        redis.stop()


def test_unreachable_redis_answers_503_with_advice(tmp_path):
    from .harness import free_port

    env = {**FAST, "FREECAL_QUEUE": "redis", "FREECAL_REDIS_URL": f"redis://127.0.0.1:{free_port()}/0"}
    svc = Service(tmp_path / "data", tmp_path, env, workers=0).start()
    try:
        r = svc.client.post("/api/jobs", json={"observations": synthetic("radial").train.to_json(), "method": "bspline", "settings": QUICK})
        assert r.status_code == 503 and "Redis at redis://127.0.0.1" in r.json()["detail"]
        assert svc.client.get("/api/jobs").json()["count"] == 0
    finally:
        svc.stop()

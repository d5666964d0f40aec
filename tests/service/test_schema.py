"""Issue 17, item 13: the OpenAPI schema agrees with the answers.

schemathesis (its default checks: no 5xx, documented status codes and content types,
bodies matching their schemas, documented Allow headers, invalid input refused, ...)
against a real `freecal serve` (no worker, the 3D view on) over real HTTP, with a bounded number of
examples per operation and a fixed seed, so a run takes well under a minute.
"""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from .harness import FAST, Service

pytestmark = pytest.mark.slow

CONFIG = Path(__file__).with_name("schemathesis.toml")
EXAMPLES, SEED = 25, 17


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    root = tmp_path_factory.mktemp("schema")
    svc = Service(root / "data", root, {**FAST, "FREECAL_VIEWER_PORT": "0"}, workers=0).start()
    yield svc
    svc.stop()


def test_errors_are_documented_as_they_are_answered(service):
    schema = service.client.get("/openapi.json").json()
    assert "HTTPValidationError" not in schema["components"]["schemas"]
    message = {"$ref": "#/components/schemas/Message"}
    for path, op in (("/api/jobs", "post"), ("/api/sets", "post")):
        responses = schema["paths"][path][op]["responses"]
        for status in ("400", "403", "413", "422", "431"):
            assert responses[status]["content"]["application/json"]["schema"] == message, (path, status)
    r = service.client.post("/api/jobs", json={})
    assert r.status_code == 422 and isinstance(r.json()["detail"], str)


def test_schemathesis_default_checks_pass(service, tmp_path):
    pytest.importorskip("schemathesis", reason="schemathesis is in the test extra: pip install -e .[test]")
    exe = shutil.which("schemathesis", path=str(Path(sys.executable).parent))
    assert exe, "the schemathesis command is not installed beside this Python"
    out = subprocess.run([exe, "--config-file", str(CONFIG), "run", f"{service.client.base_url}/openapi.json",
                          "--max-examples", str(EXAMPLES), "--seed", str(SEED), "--workers", "1",
                          "--report-dir", str(tmp_path)],
                         capture_output=True, text=True, timeout=240, cwd=tmp_path)
    assert out.returncode == 0, out.stdout[-6000:] + out.stderr[-2000:]

"""Fixtures the service's tests share."""
from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def server():
    """A real viser server on a free port, for the 3D scene's tests."""
    viser = pytest.importorskip("viser")
    srv = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield srv
    srv.stop()

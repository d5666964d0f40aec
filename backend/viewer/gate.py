"""The lock on viser's own port: only the API's /viewer proxy may open its websocket.

viser 1.1 has no hook to refuse a handshake (its ``process_request`` is its own
file server), but its websocket server runs its connect callbacks before it sends
a byte (its message producers start after them), with the connection, request
headers and all, already in ``_live_connections``. ``ProxyOnly`` is one of those
callbacks: a connection that lacks this process's key (``KEY_HEADER``, a random
secret only the proxy knows and adds) or that carries an ``Origin`` (a browser
always sends one; the proxy sends none: it checked the browser's) is closed at once
(1008), before any scene message. Only connections it let in are ``admitted``:
the viewer builds a tab's scene and job list for those alone, so a message queued
before the close, or a connection that came in while the server was starting,
still gets nothing of freecal's.

The proxy also passes what the tab asked for (``JOB_HEADER``: the job on the
page's screen; ``PAIR_HEADER``: the page's pairing key, for the selected view both
ways), read from the browser's websocket URL: viser's client cannot hand its URL
to the server, but the handshake's headers reach this callback. They are kept
for admitted connections only (``asked``), so no one bypassing the proxy can
choose what another tab shows.

viser's port also serves viser's static client files (the same in every install);
they hold no data.
"""
from __future__ import annotations

import hmac
import secrets
from dataclasses import dataclass
from typing import Any

KEY_HEADER = "X-Freecal-Viewer-Key"
JOB_HEADER = "X-Freecal-Viewer-Job"
PAIR_HEADER = "X-Freecal-Viewer-Pair"
REFUSED = "connect through /viewer on the freecal API's port"


@dataclass(frozen=True)
class Asked:
    """What a tab's URL asked for: a job to open on, and the page it is paired with (either may be empty)."""

    job_id: str = ""
    pair: str = ""


class ProxyOnly:
    def __init__(self, viser_server: Any):
        self.key = secrets.token_urlsafe(32)
        self._infra = viser_server._websock_server   # viser 1.1: the websocket server under ViserServer
        self._admitted: dict[int, Asked] = {}
        self._infra.on_client_connect(self._check)
        self._infra.on_client_disconnect(lambda conn: self._admitted.pop(conn.client_id, None))

    def admitted(self, client_id: int) -> bool:
        return client_id in self._admitted

    def asked(self, client_id: int) -> Asked:
        return self._admitted.get(client_id, Asked())

    async def _check(self, conn: Any) -> None:
        connection = self._infra._live_connections.get(conn.client_id)
        headers = connection.request.headers if connection is not None and connection.request else {}
        given = headers.get(KEY_HEADER, "")
        if hmac.compare_digest(given.encode(), self.key.encode()) and "Origin" not in headers:
            self._admitted[conn.client_id] = Asked(headers.get(JOB_HEADER, ""), headers.get(PAIR_HEADER, ""))
        elif connection is not None:
            await connection.close(1008, REFUSED)

"""Which names and which sites the service answers: the defence against DNS rebinding and
cross-site writes, for every request (HTTP and websocket), token or not.

- **Host**: a page on ``evil.example`` can make a browser send its requests to this
  server by pointing its own name at 127.0.0.1 (DNS rebinding); those requests carry
  ``Host: evil.example``. So the Host must be a name of this server: the loopback names
  (``localhost``, ``*.localhost``, 127.0.0.1, ::1), the address it is bound to, any IP
  address when it is bound to all interfaces (an address cannot be rebound, only a
  name), and the names in ``FREECAL_ALLOWED_HOSTS`` (``*``: any). Else 400.
- **Origin**: a page of another site may still *send* a form or a ``fetch`` here (the
  browser only hides the answer), so POST/PUT/PATCH/DELETE whose ``Origin`` (or, when
  absent, ``Referer``) is another site than the server's own (the Host it was reached
  by) or one of ``FREECAL_CORS_ORIGINS`` answer 403. Websockets are checked the same
  way (cross-site websocket hijacking of the 3D view). Requests without either header
  (curl, the CLI, scripts) are not from a page and pass.
"""
from __future__ import annotations

import ipaddress
from dataclasses import dataclass
from urllib.parse import urlsplit

from starlette.datastructures import Headers

from .asgi import ASGIApp, Scope, Send, refuse

LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "::1"})
ALL_INTERFACES = frozenset({"0.0.0.0", "::", ""})
WRITES = frozenset({"POST", "PUT", "PATCH", "DELETE"})


def split_host(host: str) -> tuple[str, str]:
    """``'[::1]:8000'`` → ``('::1', '8000')``; ``'Example.COM.'`` → ``('example.com', '')``."""
    host = host.strip().lower()
    if host.startswith("["):
        name, _, rest = host[1:].partition("]")
        return name, rest.lstrip(":")
    name, _, port = host.rpartition(":") if host.count(":") == 1 else (host, "", "")
    return name.rstrip("."), port


def is_ip(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
        return True
    except ValueError:
        return False


def origin_of(url: str) -> str | None:
    """``'https://Cal.example:8443/page'`` → ``'https://cal.example:8443'``: the origin of an Origin or
    Referer value, as browsers write it (no default port); None for ``null`` or a non-http(s) page."""
    parts = urlsplit(url.strip())
    if parts.scheme not in ("http", "https") or not parts.netloc:
        return None
    return f"{parts.scheme}://{parts.netloc.lower()}"


@dataclass(frozen=True)
class Allowed:
    """The names and origins of one server, from its settings."""

    names: frozenset[str]
    any_name: bool
    any_ip: bool
    origins: frozenset[str]   # as origin_of writes them

    @classmethod
    def of(cls, settings) -> Allowed:
        extra = {split_host(h)[0] for h in settings.allowed_hosts.split(",") if h.strip()}
        bound = split_host(settings.host)[0]
        origins = {origin_of(o.rstrip("/")) for o in settings.cors_origins.split(",") if o.strip()}
        return cls(names=frozenset(LOOPBACK_NAMES | extra | ({bound} - ALL_INTERFACES)), any_name="*" in extra,
                   any_ip=bound in ALL_INTERFACES, origins=frozenset(o for o in origins if o))

    def host_ok(self, host: str) -> bool:
        name, _ = split_host(host)
        return (not name  # no Host at all (HTTP/1.0): not a browser, so not a rebinding
                or self.any_name or name in self.names or name.endswith(".localhost")
                or (self.any_ip and is_ip(name)))

    def origin_ok(self, origin: str, host: str) -> bool:
        """The page is this server's (the name and port it was reached by: the scheme is left out, so
        that a TLS proxy in front changes nothing) or a listed origin."""
        page = origin_of(origin)
        return page is not None and (page.partition("://")[2] == host.strip().lower() or page in self.origins)


class OriginGuard:
    """Pure ASGI middleware: Host on every request, Origin on writes and websockets (see above)."""

    def __init__(self, app: ASGIApp, allowed: Allowed):
        self.app, self.allowed = app, allowed

    async def __call__(self, scope: Scope, receive, send: Send) -> None:
        if scope["type"] in ("http", "websocket"):
            problem = self.problem(scope)
            if problem is not None:
                await refuse(scope, send, *problem)
                return
        await self.app(scope, receive, send)

    def problem(self, scope: Scope) -> tuple[int, str] | None:
        headers = Headers(scope=scope)
        host = headers.get("host", "")
        if not self.allowed.host_ok(host):
            return 400, (f"this server does not answer to the name {split_host(host)[0]!r} (Host header): "
                         "reach it by an address or a name it knows (127.0.0.1, localhost), or, if it should "
                         "answer to that name, add it to FREECAL_ALLOWED_HOSTS on the server")
        if scope["type"] == "http" and scope["method"] not in WRITES:
            return None
        origin = headers.get("origin") or headers.get("referer")
        if origin is None or self.allowed.origin_ok(origin, host):
            return None
        return 403, (f"refused: this request comes from a page of another site ({origin_of(origin) or origin}), "
                     "and this server takes changes and 3D-view connections only from its own page: open "
                     f"the page this server serves (http://{host}/) instead, or, if that site is trusted, "
                     "list its origin in FREECAL_CORS_ORIGINS on the server")

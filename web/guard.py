"""What every request passes before it reaches a route, and every response gets on its way out.

* **Host check** (DNS rebinding): a web page on another site can make a browser send requests to the bench
  server on the operator's own loopback interface, under a name of its own that it points at 127.0.0.1. The
  server answers only requests whose ``Host`` is one of its own names (127.0.0.1, localhost, [::1], the host it
  was configured with, and :attr:`~web.settings.WebSettings.allowed_hosts`) with the port it answers on;
  any other gets 400.
* **Body limit**: a request body larger than :attr:`~web.settings.WebSettings.max_body_bytes` (64 KiB by
  default; the largest campaign is a few KiB) is refused with 413 before anything parses it, by its
  ``Content-Length`` when it sends one, else as soon as the bytes read pass the limit. Under
  :data:`FIELD_PREFIX` (a field CSV posted whole: a 2-hour track at 1 Hz is ~600 KB) the limit is
  :attr:`~web.settings.WebSettings.field_max_body_bytes` (4 MiB by default) instead. A JSON body nested
  deeper than :data:`MAX_JSON_DEPTH` is refused with 422 before the JSON parser recurses into it.
* **Security headers** on every response: a Content-Security-Policy that lets the pages load only this
  server's scripts (plotly.js included: it is served from the installed package), no framing
  (``X-Frame-Options: DENY``), no MIME sniffing, no referrer sent elsewhere.

A plain ASGI middleware, so an event stream passes through it untouched.
"""

from __future__ import annotations

import json
import re

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from .settings import WebSettings

#: Names a loopback server answers to, whatever it was configured with
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "[::1]")
#: Deepest JSON nesting a request may have (a campaign nests 4 levels)
MAX_JSON_DEPTH = 32
#: Paths whose bodies may be as large as WebSettings.field_max_body_bytes (the field data routes)
FIELD_PREFIX = "/api/field/"

#: What the pages need: their own scripts and styles, plotly's inline styles and data: images, the API
CONTENT_SECURITY_POLICY = ("default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; "
                           "img-src 'self' data: blob:; font-src 'self' data:; connect-src 'self'; "
                           "object-src 'none'; base-uri 'none'; form-action 'self'; frame-ancestors 'none'")
SECURITY_HEADERS = {
    "content-security-policy": CONTENT_SECURITY_POLICY,
    "x-frame-options": "DENY",
    "x-content-type-options": "nosniff",
    "referrer-policy": "no-referrer",
    "cross-origin-opener-policy": "same-origin",
}
_ENCODED_HEADERS = [(k.encode(), v.encode()) for k, v in SECURITY_HEADERS.items()]

_JSON_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"', re.DOTALL)
_BRACKET = re.compile(rb"[\[\]{}]")


class _TooLarge(Exception):
    pass


def json_depth(body: bytes) -> int:
    """The deepest nesting of arrays and objects in a JSON text (strings skipped), without parsing it."""
    depth = deepest = 0
    for match in _BRACKET.finditer(_JSON_STRING.sub(b'""', body)):
        if match.group() in (b"[", b"{"):
            depth += 1
            deepest = max(deepest, depth)
        else:
            depth -= 1
    return deepest


def split_host(host: str) -> tuple[str, int | None]:
    """``"name:port"`` → (name, port); the port None when absent, -1 when it is not a number."""
    if host.startswith("["):  # an IPv6 literal: [::1]:8000
        name, _, rest = host.partition("]")
        name += "]"
        port = rest[1:] if rest.startswith(":") else None
    else:
        name, sep, port = host.rpartition(":")
        if not sep:
            name, port = host, None
    if port is None:
        return name.lower(), None
    return name.lower(), int(port) if port.isdigit() else -1


class Guard:
    """The host check, the body limit and the security headers (see the module docstring)."""

    def __init__(self, app: ASGIApp, settings: WebSettings):
        self.app = app
        self.max_body = settings.max_body_bytes
        self.field_max_body = settings.field_max_body_bytes
        names = set(LOOPBACK_HOSTS) | {h.lower() for h in settings.allowed_hosts}
        if settings.host not in ("0.0.0.0", "::", ""):  # a wildcard bind is not a name clients use
            names.add(f"[{settings.host}]" if ":" in settings.host else settings.host.lower())
        self.hosts = frozenset(names)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        send = self._with_headers(send) if scope["type"] == "http" else send
        refusal = self._host_refusal(scope)
        if refusal is not None:
            await self._answer(scope, send, 400, refusal)
            return
        if scope["type"] == "http":
            headers = dict(scope.get("headers") or [])
            length = headers.get(b"content-length")
            if length is not None or b"chunked" in headers.get(b"transfer-encoding", b""):
                limit = self.body_limit(scope.get("path", ""))
                if length is not None and (not length.isdigit() or int(length) > limit):
                    await self._answer(scope, send, 413, self._too_large(limit))
                    return
                try:
                    body = await self._read_body(receive, limit)
                except _TooLarge:
                    await self._answer(scope, send, 413, self._too_large(limit))
                    return
                if body.lstrip()[:1] in (b"{", b"[") and json_depth(body) > MAX_JSON_DEPTH:
                    await self._answer(scope, send, 422, f"the JSON body nests deeper than {MAX_JSON_DEPTH} levels")
                    return
                receive = self._replay(body, receive)
        await self.app(scope, receive, send)

    def _host_refusal(self, scope: Scope) -> str | None:
        host = next((v.decode("latin-1") for k, v in scope.get("headers") or [] if k == b"host"), "")
        name, port = split_host(host)
        server = scope.get("server")
        own_port = server[1] if server and server[1] is not None else None
        default = 443 if scope.get("scheme") in ("https", "wss") else 80
        if name in self.hosts and (port == own_port or own_port is None or (port is None and own_port == default)):
            return None
        return (f"host {host!r} is not this server's: it answers to {', '.join(sorted(self.hosts))}"
                f"{f' on port {own_port}' if own_port else ''} (sunbench serve --allowed-host adds a name)")

    def body_limit(self, path: str) -> int:
        """The largest body a request to `path` may send [bytes]."""
        return self.field_max_body if path.startswith(FIELD_PREFIX) else self.max_body

    @staticmethod
    def _too_large(limit: int) -> str:
        return f"the request body is larger than {limit} bytes, the largest this API takes at this path"

    @staticmethod
    async def _read_body(receive: Receive, limit: int) -> bytes:
        chunks, size = [], 0
        while True:
            message = await receive()
            if message["type"] != "http.request":  # the client went away
                break
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > limit:
                raise _TooLarge()
            chunks.append(chunk)
            if not message.get("more_body", False):
                break
        return b"".join(chunks)

    @staticmethod
    def _replay(body: bytes, receive: Receive) -> Receive:
        sent = False

        async def replay() -> Message:
            nonlocal sent
            if not sent:
                sent = True
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()  # then what the connection says (a disconnect)
        return replay

    @staticmethod
    def _with_headers(send: Send) -> Send:
        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                present = {k.lower() for k, _ in message.get("headers", [])}
                extra = [(k, v) for k, v in _ENCODED_HEADERS if k not in present]
                message = {**message, "headers": [*message.get("headers", []), *extra]}
            await send(message)
        return send_with_headers

    @staticmethod
    async def _answer(scope: Scope, send: Send, status: int, detail: str) -> None:
        if scope["type"] == "websocket":
            await send({"type": "websocket.close", "code": 1008, "reason": detail[:120]})
            return
        body = json.dumps({"detail": detail}).encode()
        await send({"type": "http.response.start", "status": status,
                    "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()),
                                (b"connection", b"close")]})
        await send({"type": "http.response.body", "body": body})

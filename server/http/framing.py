"""ASGI middleware: a request framed two ways is refused (400) and its connection closed.

A request with both ``Content-Length`` and ``Transfer-Encoding`` says two different things about
where its body ends. uvicorn's h11 reads it by its chunked body and keeps the connection open, so
the bytes after the chunks — which an intermediary that frames by ``Content-Length`` forwarded
as this request's body — are answered as a request of their own: the precondition of request
smuggling. RFC 9112 §6.1 lets a server answer such a request 400 or close the connection after
it; this answers 400 with ``Connection: close`` (h11 then closes the connection once the answer
is written, and the bytes behind it are never parsed) before any other part of the service — the
body limit among them, which would trust the ``Content-Length`` the chunks do not keep to. A
WebSocket upgrade so framed is refused as well (403, before the handshake). uvicorn's httptools
parser refuses these requests itself; this holds under either.
"""

from __future__ import annotations

import json
from collections.abc import Awaitable, Callable
from typing import Any

Scope = dict[str, Any]
Message = dict[str, Any]
ASGIApp = Callable[[Scope, Callable[[], Awaitable[Message]], Callable[[Message], Awaitable[None]]], Awaitable[None]]

DETAIL = (
    "the request has both Content-Length and Transfer-Encoding (RFC 9112 §6.1: its body would end in "
    "two places); send one of them — Content-Length for a body of known size"
)


def framed_twice(scope: Scope) -> bool:
    """Whether the request's headers carry both Content-Length and Transfer-Encoding."""
    names = {bytes(name).lower() for name, _ in scope.get("headers") or ()}
    return b"content-length" in names and b"transfer-encoding" in names


class SingleFraming:
    """Wraps an ASGI app: requests framed by both headers get 400 ``{"detail"}`` and ``Connection: close``."""

    def __init__(self, app: ASGIApp):
        self.app = app

    async def __call__(self, scope: Scope, receive, send) -> None:
        if scope["type"] not in ("http", "websocket") or not framed_twice(scope):
            await self.app(scope, receive, send)
            return
        if scope["type"] == "websocket":
            await send({"type": "websocket.close", "code": 1008, "reason": "Content-Length and Transfer-Encoding"})
            return
        body = json.dumps({"detail": DETAIL}).encode()
        await send(
            {
                "type": "http.response.start",
                "status": 400,
                "headers": [
                    (b"content-type", b"application/json"),
                    (b"content-length", str(len(body)).encode()),
                    (b"connection", b"close"),
                ],
            }
        )
        await send({"type": "http.response.body", "body": body, "more_body": False})

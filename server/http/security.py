"""ASGI middleware: the browser-facing security headers of every answer.

- ``Content-Security-Policy``: :data:`CLIENT_POLICY` — the phone client's needs and nothing more:
  its own scripts (ES modules, no inline script), style sheet and fetches (``connect-src 'self'``
  covers the same-origin WebSocket too), the ``data:`` URL of its empty favicon; no plugin, no
  ``<base>``, and no page may frame it (``frame-ancestors 'none'``: a framed client could be
  clicked through by the framing page). An answer that sets its own policy keeps it: the offline
  API docs (``/docs``, ``/redoc``) get :func:`docs_policy`, which allows their inline script by
  its hash and the styles and workers Swagger UI and ReDoc make at run time.
- ``X-Content-Type-Options: nosniff``: a body is what its ``Content-Type`` says (an uploaded
  model or a frame is never run as a script or shown as a page).
- ``X-Frame-Options: DENY``: ``frame-ancestors 'none'`` for browsers that predate it.
- ``Referrer-Policy: no-referrer``: the client's URLs (session ids in paths) are not sent
  elsewhere.

API answers carry the same headers: harmless for ``fetch``, and a JSON or image answer opened
as a page runs nothing.
"""

from __future__ import annotations

import base64
import hashlib
import re
from typing import Any

CSP = "content-security-policy"

CLIENT_POLICY = "; ".join(
    (
        "default-src 'self'",
        "script-src 'self'",
        "style-src 'self'",
        "img-src 'self' data:",
        "connect-src 'self'",
        "object-src 'none'",
        "base-uri 'none'",
        "form-action 'self'",
        "frame-ancestors 'none'",
    )
)

HEADERS: tuple[tuple[bytes, bytes], ...] = (
    (CSP.encode(), CLIENT_POLICY.encode()),
    (b"x-content-type-options", b"nosniff"),
    (b"x-frame-options", b"DENY"),
    (b"referrer-policy", b"no-referrer"),
)

_INLINE_SCRIPT = re.compile(rb"<script>(.*?)</script>", re.DOTALL)


def docs_policy(html: bytes) -> str:
    """The policy of an offline docs page (Swagger UI, ReDoc): its own files, its inline scripts by
    their SHA-256 (FastAPI writes Swagger UI's start-up script into the page), the styles both
    libraries insert at run time, ReDoc's search worker (a ``blob:`` URL) and the ``data:`` images
    of their style sheets."""
    hashes = " ".join(
        f"'sha256-{base64.b64encode(hashlib.sha256(m.group(1)).digest()).decode()}'"
        for m in _INLINE_SCRIPT.finditer(html)
    )
    return "; ".join(
        (
            "default-src 'self'",
            f"script-src 'self' {hashes}".rstrip(),
            "style-src 'self' 'unsafe-inline'",
            "img-src 'self' data:",
            "worker-src 'self' blob:",
            "connect-src 'self'",
            "object-src 'none'",
            "base-uri 'none'",
            "frame-ancestors 'none'",
        )
    )


class SecurityHeaders:
    """Wraps an ASGI app: every HTTP answer gets :data:`HEADERS`, each unless the answer set it."""

    def __init__(self, app: Any):
        self.app = app

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def send_with_headers(message: dict) -> None:
            if message["type"] == "http.response.start":
                headers = list(message.get("headers", ()))
                present = {bytes(name).lower() for name, _ in headers}
                headers.extend((name, value) for name, value in HEADERS if name not in present)
                message = {**message, "headers": headers}
            await send(message)

        await self.app(scope, receive, send_with_headers)

"""ASGI middleware: ``OPTIONS`` and methods a path does not take, answered with the right ``Allow``.

Starlette answers a method a route does not take with the ``Allow`` of the first route whose
path matched — one of several for ``/api/sessions/{id}`` (GET and DELETE are two routes) — and,
because the client's static files are mounted at ``/``, a plain ``OPTIONS`` reached that mount
and came back 405 ``Allow: GET, HEAD``, which is wrong for the API's paths. Here the methods of *every* route whose
path matches are collected:

- ``OPTIONS`` (not a CORS preflight, which carries ``Access-Control-Request-Method`` and is
  left to Starlette's ``CORSMiddleware``) → 204 with ``Allow`` (those methods and OPTIONS);
- a method none of them takes → 405 ``{"detail"}`` with the same ``Allow``;
- a plain ``OPTIONS`` of a path nothing serves → 404; the client's static files answer
  ``GET, HEAD`` (when the file exists);
- anything else passes through.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from starlette.routing import Match, Mount
from starlette.staticfiles import StaticFiles

Scope = dict[str, Any]
METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE")


def _routes(app: Any) -> list[Any]:
    """The app's routes but its mounts (the static files at ``/`` take any path)."""
    return [r for r in getattr(app, "routes", ()) if not isinstance(r, Mount)]


def takes(routes: list[Any], scope: Scope, method: str) -> bool:
    """Some route takes ``method`` on ``scope``'s path. Asked through ``matches`` on a copy of the
    scope, the one question every route (FastAPI's included routers too) answers."""
    probe = {**scope, "method": method}
    return any(route.matches(probe)[0] is Match.FULL for route in routes)


def _static_serves(app: StaticFiles, scope: Scope) -> bool:
    """Whether the static app would answer GET with a file for this (mount-relative) scope."""
    try:
        path = app.get_path(scope)
        full, stat = app.lookup_path(path)
        if stat is None:
            return False
        if Path(full).is_dir():
            return bool(app.html) and app.lookup_path(str(Path(path) / "index.html"))[1] is not None
        return True
    except Exception:
        return False


def static_methods(app: Any, scope: Scope) -> set[str]:
    """``GET, HEAD`` where a static mount (the client, the shaders, the docs' assets) has the file."""
    probe = {**scope, "method": "GET"}
    for route in getattr(app, "routes", ()):
        if isinstance(route, Mount) and isinstance(route.app, StaticFiles):
            match, child = route.matches(probe)
            if match is Match.FULL and _static_serves(route.app, {**probe, **child}):
                return {"GET", "HEAD"}
    return set()


def allowed_methods(app: Any, scope: Scope) -> set[str]:
    """The methods the app takes on ``scope``'s path (empty: nothing serves this path)."""
    routes = _routes(app)
    return {m for m in METHODS if takes(routes, scope, m)} or static_methods(app, scope)


class AllowMethods:
    """Wraps an ASGI app (the Starlette application is read from ``scope["app"]``)."""

    def __init__(self, app: Any):
        self.app = app

    async def __call__(self, scope: Scope, receive, send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        method = scope["method"]
        headers = dict(scope.get("headers") or [])
        if method == "OPTIONS" and b"access-control-request-method" in headers and b"origin" in headers:
            await self.app(scope, receive, send)  # a CORS preflight: CORSMiddleware's
            return
        app = scope.get("app")
        if method != "OPTIONS" and takes(_routes(app), scope, method):
            await self.app(scope, receive, send)  # the common case: one matching pass
            return
        methods = allowed_methods(app, scope)
        if method == "OPTIONS" and not methods:
            await _answer(send, 404, b"", json.dumps({"detail": "Not Found"}).encode())
            return
        if not methods or method in methods:  # a 404, or a static file's GET/HEAD
            await self.app(scope, receive, send)
            return
        allow = ", ".join(sorted(methods | {"OPTIONS"})).encode()
        if method == "OPTIONS":
            await _answer(send, 204, allow, b"")
        else:
            detail = f"method {method} is not allowed here; this path takes {allow.decode()}"
            await _answer(send, 405, allow, json.dumps({"detail": detail}).encode())


async def _answer(send, status: int, allow: bytes, body: bytes) -> None:
    headers = [(b"allow", allow)] if allow else []
    if body:
        headers += [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": body})

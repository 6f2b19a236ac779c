"""The HTTP and WebSocket API: dependencies, the error table, and the routes by resource.

:data:`api_router` holds every route under ``/api``; :func:`server.app.create_app` includes it
and installs :func:`server.api.errors.install` (docs/API.md describes the API).
"""

from __future__ import annotations

from fastapi import APIRouter

from .routes import device, frames, meta, sessions, ws

api_router = APIRouter(prefix="/api")
# Tags group the OpenAPI document (server.web.OPENAPI_TAGS); device's router names its own.
for _routes, _tags in (
    (sessions, ["sessions"]),
    (frames, ["frames"]),
    (meta, ["service"]),
    (ws, ["frames"]),
    (device, []),
):
    api_router.include_router(_routes.router, tags=[*_tags])

__all__ = ["api_router"]

"""The routes, one module per resource: sessions, frames, meta, device, ws, and ``/metrics``.

:data:`api_router` holds every route under ``/api``; ``/metrics`` (:mod:`.metrics`) is outside it.
"""

from __future__ import annotations

from fastapi import APIRouter

from . import device, frames, meta, sessions, ws

api_router = APIRouter(prefix="/api")
# Tags group the OpenAPI document (server.http.cors_docs.OPENAPI_TAGS); device's router names its own.
for _routes, _tags in (
    (sessions, ["sessions"]),
    (frames, ["frames"]),
    (meta, ["service"]),
    (ws, ["frames"]),
    (device, []),
):
    api_router.include_router(_routes.router, tags=[*_tags])

__all__ = ["api_router"]

"""The HTTP and WebSocket API: dependencies, the error table, and the routes by resource.

:data:`api_router` holds every route under ``/api``; :func:`server.app.create_app` includes it
and installs :func:`server.api.errors.install` (docs/API.md describes the API).
"""

from __future__ import annotations

from fastapi import APIRouter

from .routes import device, frames, meta, sessions, ws

api_router = APIRouter(prefix="/api")
for _routes in (sessions, frames, meta, ws, device):
    api_router.include_router(_routes.router)

__all__ = ["api_router"]

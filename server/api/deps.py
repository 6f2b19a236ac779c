"""What routes depend on: the process's service and GL worker, the session-id path
parameter, and the frame parameters of a query.

The service and the worker live on ``app.state`` (the lifespan makes them), never in
globals, so every app of a test process has its own.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import Depends, Path, Query
from starlette.requests import HTTPConnection

from ..gl_worker import GLWorker
from ..models import FrameQuery
from ..service import SessionService


def get_service(conn: HTTPConnection) -> SessionService:
    """The process's SessionService (created by the lifespan)."""
    return conn.app.state.service


def get_worker(conn: HTTPConnection) -> GLWorker:
    """The process's GL thread and its queue (created by the lifespan)."""
    return conn.app.state.worker


ServiceDep = Annotated[SessionService, Depends(get_service)]
WorkerDep = Annotated[GLWorker, Depends(get_worker)]

# secrets.token_urlsafe(24) makes 32 characters; 64 leaves room and bounds what is looked up.
SessionId = Annotated[str, Path(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_-]+$",
                                description="session token from POST /api/sessions")]


def frame_params(query: Annotated[FrameQuery, Query()]) -> dict[str, Any]:
    """The render settings a frame's query names; missing ones come from the session's defaults."""
    return query.given()


FrameParams = Annotated[dict[str, Any], Depends(frame_params)]

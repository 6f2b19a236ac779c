"""What routes depend on: the process's session service and frame pipeline, the rate of session
creations, and the session-id path parameter.

The service and the pipeline live on ``app.state`` (the lifespan makes them), never in
globals, so every app of a test process has its own.
"""

from __future__ import annotations

import threading
from typing import Annotated

from fastapi import Depends, Path
from starlette.requests import HTTPConnection

from ..frames.pipeline import FramePipeline
from ..sessions.ratelimit import TokenBuckets, client_key
from ..sessions.service import SessionService


def get_service(conn: HTTPConnection) -> SessionService:
    """The process's SessionService (created by the lifespan)."""
    return conn.app.state.service


def get_frames(conn: HTTPConnection) -> FramePipeline:
    """The process's frame pipeline (created by the lifespan)."""
    return conn.app.state.frames


_limiter_lock = threading.Lock()


def session_create_rate(conn: HTTPConnection) -> None:
    """Takes a token of the client address's bucket (POCKETRAY_SESSION_CREATE_PER_MIN, _BURST);
    :class:`server.sessions.ratelimit.RateLimited` (429) when it has none. The buckets are made on first
    use, one set per app, like everything else on ``app.state``."""
    state = conn.app.state
    limiter = getattr(state, "session_create_buckets", None)
    if limiter is None:
        with _limiter_lock:
            limiter = getattr(state, "session_create_buckets", None)
            if limiter is None:
                config = state.config
                limiter = state.session_create_buckets = TokenBuckets(
                    config.session_create_per_min, config.session_create_burst
                )
    limiter.take(client_key(conn.client.host if conn.client else None))


ServiceDep = Annotated[SessionService, Depends(get_service)]
FramesDep = Annotated[FramePipeline, Depends(get_frames)]
SessionCreateRate = Depends(session_create_rate)

# secrets.token_urlsafe(24) makes 32 characters; 64 leaves room and bounds what is looked up.
SessionId = Annotated[
    str,
    Path(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_-]+$", description="session token from POST /api/sessions"),
]

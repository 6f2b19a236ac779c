"""Every error answer of the API, in one table: exception → (status, detail, headers).

The HTTP exception handlers (:func:`install`) and the WebSocket route
(:mod:`server.api.routes.ws`) both answer from :func:`answer`, so an error reads the
same over either transport: over HTTP as the status, ``{"detail": …}`` and its headers;
over the WebSocket as one text message ``{"status", "detail"}`` plus ``"retry_after"``
(seconds) where HTTP sends ``Retry-After``.

- 422: bad input. ``detail`` is a list of ``{"loc", "msg", "type"}``, ``msg`` starting with
  the field's path (``camera.fov_y: …``): pydantic's errors, the renderer's ``SceneError``
  (with its field) and bodies that are not even JSON (FastAPI would say 400). The service's
  parts name the field; the route names the part of the request it is in, once
  (:func:`located`: ``with located(Where.QUERY): …``).
- 404: no such session. 409: the frame was superseded (a newer frame of the session,
  latest wins) or the session changed under a gesture's frame: nothing was committed.
  503 + ``Retry-After``: queue full, busy (planning slots, large-body slots), GL
  unavailable, render timed out (Retry-After = the work queued ahead), any failure of the
  session store — never a 500 for load or the store. 429 + ``Retry-After``: a client address
  over its session creation rate, a session over its rate of new shader variants. 507 +
  ``Retry-After``: the session store's quota (POCKETRAY_MAX_STORE_BYTES) would be passed. 500: a bug (logged).
"""

from __future__ import annotations

import logging
import sqlite3
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import redis
from fastapi import FastAPI
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from fastapi.utils import is_body_allowed_for_status_code
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.requests import Request
from starlette.responses import Response

from renderer.geometry.scene import SceneError

from ..config import ServerConfig
from ..faults import Busy, NotFound, RenderTimeout, Superseded, Where, input_error
from ..frames.trace import GLNotReady, QueueFull, VariantsLimited
from ..http import metrics
from ..sessions.ratelimit import RateLimited
from ..sessions.store import StoreFull, StoreUnavailable
from .schemas import MAX_LISTED_ERRORS, ErrorOut

log = logging.getLogger("pocketray.server")

NOT_FOUND = (
    "session: no session with this id (unknown, deleted, or expired after POCKETRAY_SESSION_TTL_S "
    "seconds idle); create one with POST /api/sessions"
)
GL_RETRY_AFTER_S = 5  # a GL context that failed, or a render that timed out: try again later
STORE_RETRY_AFTER_S = 1  # the session store is usually back within a second (locked, reconnecting)
STORE_FULL_RETRY_AFTER_S = 60  # a full store frees space only as sessions are deleted or expire


@dataclass(frozen=True)
class ErrorAnswer:
    """One error answer: HTTP status, the ``detail`` of the body, HTTP headers."""

    status: int
    detail: Any
    headers: dict[str, str] = field(default_factory=dict)

    @property
    def retry_after_s(self) -> int | None:
        """Seconds until a retry may succeed (the ``Retry-After`` header), if the answer says."""
        value = self.headers.get("Retry-After")
        return int(value) if value is not None else None

    def http(self) -> Response:
        """The HTTP response: ``{"detail": …}`` (no body where the status allows none)."""
        if not is_body_allowed_for_status_code(self.status):
            return Response(status_code=self.status, headers=self.headers)
        return JSONResponse({"detail": self.detail}, status_code=self.status, headers=self.headers)

    def ws_message(self) -> dict[str, Any]:
        """The WebSocket message: ``{"status", "detail"}`` and ``"retry_after"`` (s) where HTTP has Retry-After."""
        message: dict[str, Any] = {"status": self.status, "detail": self.detail}
        if self.retry_after_s is not None:
            message["retry_after"] = self.retry_after_s
        return message


# ---- the answers ------------------------------------------------------------------------------
def _loc_label(loc: list) -> str:
    """``["body", "scene", "spheres", 3, "radius"]`` → ``scene.spheres[3].radius``."""
    inner = loc[1:] if loc and loc[0] in ("body", "query", "path", "header") else loc
    out = ""
    for part in inner:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out or (str(loc[0]) if loc else "body")


def _invalid(loc: list, msg: str, type_: str) -> ErrorAnswer:
    return ErrorAnswer(422, [{"loc": loc, "msg": msg, "type": type_}])


def _validation(exc: RequestValidationError, config: ServerConfig) -> ErrorAnswer:
    """The first MAX_LISTED_ERRORS errors, then one ``too_many_errors`` entry counting the rest.
    A long list of spheres is cut while it is validated (``SceneModel``): its own
    ``too_many_errors`` entry carries the count of the errors it did not keep."""
    found = exc.errors()
    summaries = [e for e in found if e.get("type") == "too_many_errors"]
    real = [e for e in found if e.get("type") != "too_many_errors"]
    shown = real[:MAX_LISTED_ERRORS]
    hidden = len(real) - len(shown) + sum(int((e.get("ctx") or {}).get("more", 0)) for e in summaries)
    errors = []
    for e in shown:
        loc = [x if isinstance(x, (int, str)) else str(x) for x in e.get("loc", ())]
        msg = str(e.get("msg", "invalid value"))
        errors.append({"loc": loc, "msg": f"{_loc_label(loc)}: {msg}", "type": str(e.get("type", "value_error"))})
    if hidden:
        where = summaries[0] if summaries and len(real) <= MAX_LISTED_ERRORS else real[MAX_LISTED_ERRORS]
        loc = [x if isinstance(x, (int, str)) else str(x) for x in where.get("loc", ("body",))]
        loc = loc if where in summaries else loc[:1]
        errors.append(
            {
                "loc": loc,
                "msg": f"{_loc_label(loc)}: {hidden} more errors not listed ({len(shown) + hidden} in all)",
                "type": "too_many_errors",
            }
        )
    return ErrorAnswer(422, errors)


def _http(exc: StarletteHTTPException, config: ServerConfig) -> ErrorAnswer:
    """A body that is not even JSON (FastAPI says 400) is bad input like any other: 422.
    Other HTTP errors (no such route, method not allowed) stay as Starlette made them."""
    if exc.status_code == 400:
        return _invalid(["body"], f"body: not valid UTF-8 JSON ({exc.detail})", "json_invalid")
    return ErrorAnswer(exc.status_code, exc.detail, dict(exc.headers or {}))


@contextmanager
def located(where: Where) -> Iterator[None]:
    """The part of the request (body or query) of the input errors raised inside: the service's parts
    name the field (``("width",)``), the route the part, once. An error placed already keeps its place."""
    try:
        yield
    except SceneError as e:
        placed = input_error(e).at(where)
        if placed is e:
            raise
        raise placed from None


def _scene(exc: SceneError, config: ServerConfig) -> ErrorAnswer:
    # a refusal no route placed is the body's (a request's input is its body unless the route says)
    loc = list(input_error(exc).at(Where.BODY).loc)
    return _invalid(loc, f"{exc.field}: {exc.message}", "value_error")


def _not_found(exc: NotFound, config: ServerConfig) -> ErrorAnswer:
    return ErrorAnswer(404, NOT_FOUND)


def _queue_full(exc: QueueFull, config: ServerConfig) -> ErrorAnswer:
    return ErrorAnswer(
        503,
        f"render queue full ({config.queue_size} admitted, POCKETRAY_QUEUE_SIZE); retry after {exc.retry_after_s} s",
        {"Retry-After": str(exc.retry_after_s)},
    )


def _busy(exc: Busy, config: ServerConfig) -> ErrorAnswer:
    """A bounded stage before the GL queue is full: frames being planned, large bodies being read."""
    return ErrorAnswer(503, str(exc), {"Retry-After": str(exc.retry_after_s)})


def _gl_unavailable(exc: Exception, config: ServerConfig) -> ErrorAnswer:
    return ErrorAnswer(503, f"gl: {exc}", {"Retry-After": str(GL_RETRY_AFTER_S)})


def _timeout(exc: RenderTimeout, config: ServerConfig) -> ErrorAnswer:
    """A render that did not finish in POCKETRAY_RENDER_TIMEOUT_S: it was stopped and nothing
    was committed; Retry-After is the work queued ahead."""
    return ErrorAnswer(503, f"gl: {exc}; nothing was changed", {"Retry-After": str(exc.retry_after_s)})


def _superseded(exc: Superseded, config: ServerConfig) -> ErrorAnswer:
    return ErrorAnswer(409, str(exc))


def _store_unavailable(exc: Exception, config: ServerConfig) -> ErrorAnswer:
    """Any failure of the session store — not answering, locked, a file that is gone or not a
    database, a record that does not decode, a change that kept colliding — is a 503: the request
    changed nothing it did not report, and may be retried."""
    log.error("state backend error: %s: %s", type(exc).__name__, exc)
    what = str(exc) if isinstance(exc, StoreUnavailable) else f"not answering ({type(exc).__name__})"
    return ErrorAnswer(
        503,
        f"state: the session store is {what}; retry",
        {"Retry-After": str(getattr(exc, "retry_after_s", STORE_RETRY_AFTER_S))},
    )


def _rate_limited(exc: RateLimited, config: ServerConfig) -> ErrorAnswer:
    return ErrorAnswer(
        429,
        f"sessions: this address created its {exc.burst} sessions at once and may create "
        f"{exc.per_min:g} a minute (POCKETRAY_SESSION_CREATE_BURST, "
        f"POCKETRAY_SESSION_CREATE_PER_MIN); retry after {exc.retry_after_s} s, or go on with a "
        "session it has",
        {"Retry-After": str(exc.retry_after_s)},
    )


def _variants_limited(exc: VariantsLimited, config: ServerConfig) -> ErrorAnswer:
    """A frame needing a shader variant the GL thread would compile, over its session's rate."""
    return ErrorAnswer(
        429,
        f"frame: this session has had its {exc.burst} new shader variants compiled at once and may have "
        f"{exc.per_min:g} a minute (POCKETRAY_NEW_VARIANTS_BURST, POCKETRAY_NEW_VARIANTS_PER_MIN; each new "
        "combination of method, mode, recursion depth, integrator and scene features is compiled on the "
        f"GL thread); nothing was traced: retry after {exc.retry_after_s} s, or use settings already rendered",
        {"Retry-After": str(exc.retry_after_s)},
    )


def _store_full(exc: StoreFull, config: ServerConfig) -> ErrorAnswer:
    """The store's quota would be passed: nothing was written, existing sessions go on."""
    return ErrorAnswer(
        507,
        f"state: the session store is full ({exc.used} of {exc.limit} bytes used, "
        f"POCKETRAY_MAX_STORE_BYTES; this scene needs {exc.wanted} more); space frees as sessions "
        f"are deleted or expire (POCKETRAY_SESSION_TTL_S idle): retry later, or delete a session",
        {"Retry-After": str(STORE_FULL_RETRY_AFTER_S)},
    )


def _internal(exc: Exception, config: ServerConfig) -> ErrorAnswer:
    return ErrorAnswer(500, f"internal error ({type(exc).__name__}); see the server log")


@dataclass(frozen=True)
class ErrorRow:
    """Exceptions of ``types`` are answered by ``answer(exc, config)``."""

    name: str
    types: tuple[type[Exception], ...]
    answer: Callable[[Any, ServerConfig], ErrorAnswer]


# First match wins: the catch-all Exception is last.
ERROR_TABLE: tuple[ErrorRow, ...] = (
    ErrorRow("validation", (RequestValidationError,), _validation),
    ErrorRow("http_exception", (StarletteHTTPException,), _http),
    ErrorRow("scene", (SceneError,), _scene),  # InputError is a SceneError that knows its loc
    ErrorRow("not_found", (NotFound,), _not_found),
    ErrorRow("queue_full", (QueueFull,), _queue_full),
    ErrorRow("busy", (Busy,), _busy),
    ErrorRow("timeout", (RenderTimeout,), _timeout),
    ErrorRow("gl_unavailable", (GLNotReady,), _gl_unavailable),
    ErrorRow("superseded", (Superseded,), _superseded),
    ErrorRow("rate_limited", (RateLimited,), _rate_limited),
    ErrorRow("variants_limited", (VariantsLimited,), _variants_limited),
    ErrorRow("store_full", (StoreFull,), _store_full),
    ErrorRow("store_unavailable", (StoreUnavailable, sqlite3.Error, redis.RedisError), _store_unavailable),
    ErrorRow("internal", (Exception,), _internal),
)


def row_of(exc: BaseException) -> ErrorRow:
    """The table's row for ``exc``."""
    return next(row for row in ERROR_TABLE if isinstance(exc, row.types))


def answer(exc: Exception, config: ServerConfig, where: str) -> ErrorAnswer:
    """The answer to ``exc`` raised while serving ``where`` (``"GET /api/…"``, ``"WS /api/…"``)."""
    row = row_of(exc)
    if row.name == "internal":
        log.exception("unexpected error in %s", where, exc_info=exc)
    out = row.answer(exc, config)
    if out.status == 503:
        metrics.unavailable("render_timeout" if isinstance(exc, RenderTimeout) else row.name)
    return out


# ---- HTTP ---------------------------------------------------------------------------------
def _handle(request: Request, exc: Exception) -> Response:
    return answer(exc, request.app.state.config, f"{request.method} {request.url.path}").http()


def install(app: FastAPI) -> None:
    """One handler for every exception type of the table. It looks the row up itself, so which
    of the types Starlette matched (it goes by the class hierarchy) does not matter."""
    for row in ERROR_TABLE:
        for exc_type in row.types:
            app.add_exception_handler(exc_type, _handle)


# ---- OpenAPI: the error answers a route documents ---------------------------------------------
_RETRY_AFTER_DOC = {"Retry-After": {"description": "seconds", "schema": {"type": "string"}}}
ERROR_DOCS: dict[int, dict[str, Any]] = {
    404: {"model": ErrorOut, "description": "no such session (unknown, deleted or expired)"},
    409: {
        "model": ErrorOut,
        "description": "the frame was superseded by a newer frame of this session (latest "
        "wins), or the session changed before a gesture could be committed",
    },
    413: {"model": ErrorOut, "description": "request body too large (POCKETRAY_MAX_BODY_BYTES)"},
    429: {
        "model": ErrorOut,
        "description": "this client address is over its session creation rate "
        "(POCKETRAY_SESSION_CREATE_PER_MIN); see Retry-After",
        "headers": _RETRY_AFTER_DOC,
    },
    507: {
        "model": ErrorOut,
        "description": "the session store is full (POCKETRAY_MAX_STORE_BYTES); nothing was written; see Retry-After",
        "headers": _RETRY_AFTER_DOC,
    },
    503: {
        "model": ErrorOut,
        "description": "render queue full, busy (frames being planned, large bodies being "
        "read), GL or session store not available; see Retry-After",
        "headers": _RETRY_AFTER_DOC,
    },
}


def documented(*statuses: int) -> dict[int | str, dict[str, Any]]:
    """``responses=`` of a route that can answer these error statuses."""
    return {s: ERROR_DOCS[s] for s in statuses}

"""Logs as JSON lines, each with the request's id and session id, and the per-request
middleware that sets both, writes the access line and counts the request in the metrics.

- :func:`configure_logging` gives the ``pocketray`` loggers one handler on stderr (JSON or
  text, ``POCKETRAY_LOG_FORMAT``); :func:`server.app.create_app` calls it, so the service's
  own lines (GL renderer, warm-up, errors) appear however the app is started — ``pocketray
  serve``, ``python -m server`` or a bare ``uvicorn server.app:app``. :func:`uvicorn_log_config`
  is the configuration the CLI hands uvicorn so that its lines are JSON too.
- :class:`RequestContext` (pure ASGI): the request id is the client's ``X-Request-ID`` when it
  is a short token, else a new one, and is sent back in ``X-Request-ID``; the session id is
  the ``/api/sessions/{id}/…`` path segment, else the ``X-Session-Id`` header (the balancer's
  hash key). Both live in context variables, so every line logged while serving the request
  carries them. One ``pocketray.access`` line per request (method, route, path, status, ms).
"""

from __future__ import annotations

import contextvars
import json
import logging
import re
import secrets
import sys
import time
from datetime import UTC, datetime
from typing import Any

from . import metrics

REQUEST_ID: contextvars.ContextVar[str | None] = contextvars.ContextVar("pocketray_request_id", default=None)
SESSION_ID: contextvars.ContextVar[str | None] = contextvars.ContextVar("pocketray_session_id", default=None)

REQUEST_ID_HEADER = "x-request-id"
SESSION_HEADER = "x-session-id"  # the balancer hashes on it (deploy/haproxy.cfg); the client sends it
_TOKEN = re.compile(r"^[A-Za-z0-9._:-]{1,128}$")
_SESSION_PATH = re.compile(r"^/api/sessions/([A-Za-z0-9_-]{1,64})(?:/|$)")
_RESERVED = set(vars(logging.LogRecord("", 0, "", 0, "", (), None))) | {"message", "asctime"}
_MARK = "_pocketray_handler"


class JsonFormatter(logging.Formatter):
    """One JSON object a line: time (UTC, ISO 8601), level, logger, message, request_id,
    session_id, the record's ``extra`` fields, and ``exc`` (the traceback) when there is one."""

    def format(self, record: logging.LogRecord) -> str:
        out: dict[str, Any] = {
            "time": datetime.fromtimestamp(record.created, UTC).isoformat(timespec="milliseconds"),
            "level": record.levelname.lower(),
            "logger": record.name,
            "message": record.getMessage(),
        }
        rid, sid = REQUEST_ID.get(), SESSION_ID.get()
        if rid:
            out["request_id"] = rid
        if sid:
            out["session_id"] = sid
        for key, value in record.__dict__.items():
            if key not in _RESERVED and not key.startswith("_") and key not in out:
                out[key] = value if isinstance(value, (str, int, float, bool, type(None))) else str(value)
        if record.exc_info:
            out["exc"] = self.formatException(record.exc_info)
        return json.dumps(out, ensure_ascii=False, default=str)


class TextFormatter(logging.Formatter):
    def __init__(self) -> None:
        super().__init__("%(asctime)s %(name)s %(levelname)s %(message)s")

    def format(self, record: logging.LogRecord) -> str:
        line = super().format(record)
        rid, sid = REQUEST_ID.get(), SESSION_ID.get()
        return line + (f" [request {rid}]" if rid else "") + (f" [session {sid}]" if sid else "")


def formatter(fmt: str) -> logging.Formatter:
    return JsonFormatter() if fmt == "json" else TextFormatter()


def _level(name: str) -> int:
    level = logging.getLevelName(str(name).upper())
    return level if isinstance(level, int) else logging.INFO


def configure_logging(level: str = "info", fmt: str = "json") -> None:
    """The ``pocketray`` loggers write to stderr in ``fmt`` at ``level`` (idempotent: a second
    call replaces the handler it made; handlers someone else added stay)."""
    logger = logging.getLogger("pocketray")
    for h in list(logger.handlers):
        if getattr(h, _MARK, False):
            logger.removeHandler(h)
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(formatter(fmt))
    setattr(handler, _MARK, True)
    logger.addHandler(handler)
    logger.setLevel(_level(level))
    logger.propagate = False


def uvicorn_log_config(level: str = "info", fmt: str = "json") -> dict[str, Any]:
    """uvicorn's ``log_config``: its own lines (start-up, shutdown, errors) in ``fmt`` on stderr.
    Its access log is off: :class:`RequestContext` writes one line per request instead."""
    return {
        "version": 1,
        "disable_existing_loggers": False,
        "formatters": {"pocketray": {"()": f"{__name__}.{'JsonFormatter' if fmt == 'json' else 'TextFormatter'}"}},
        "handlers": {
            "stderr": {"class": "logging.StreamHandler", "formatter": "pocketray", "stream": "ext://sys.stderr"}
        },
        "loggers": {
            "uvicorn": {"handlers": ["stderr"], "level": level.upper(), "propagate": False},
            "uvicorn.error": {"level": level.upper()},
            "uvicorn.access": {"handlers": [], "level": "WARNING", "propagate": False},
        },
    }


access_log = logging.getLogger("pocketray.access")


def _header(scope: dict, name: bytes) -> str | None:
    for k, v in scope.get("headers") or ():
        if k == name:
            return v.decode("latin-1")
    return None


def route_template(scope: dict) -> str:
    """The matched route's path template (FastAPI puts the route in the scope), else a fixed label."""
    context = (scope.get("fastapi") or {}).get("effective_route_context")  # FastAPI ≥ 0.13x: the full path
    path = getattr(context, "path_format", None) or getattr(scope.get("route"), "path_format", None)
    if path:
        return path
    return "static" if scope.get("type") == "http" else "other"


class RequestContext:
    """Request id + session id for every HTTP request and WebSocket; access log; HTTP metrics."""

    def __init__(self, app: Any):
        self.app = app

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        given = _header(scope, REQUEST_ID_HEADER.encode())
        rid = given if given and _TOKEN.match(given) else secrets.token_hex(8)
        m = _SESSION_PATH.match(scope.get("path", ""))
        sid = m.group(1) if m else _header(scope, SESSION_HEADER.encode())
        sid = sid if sid and _TOKEN.match(sid) else None
        t_rid, t_sid = REQUEST_ID.set(rid), SESSION_ID.set(sid)
        status = {"code": 500}
        t0 = time.perf_counter()

        async def send_with_id(message: dict) -> None:
            if message["type"] == "http.response.start":
                status["code"] = message["status"]
                message = {**message, "headers": [*message.get("headers", ()), (b"x-request-id", rid.encode())]}
            await send(message)

        try:
            if scope["type"] == "websocket":
                await self.app(scope, receive, send)
                return
            await self.app(scope, receive, send_with_id)
        finally:
            if scope["type"] == "http":
                dt = time.perf_counter() - t0
                route = route_template(scope)
                metrics.http_request(scope["method"], route, status["code"], dt)
                access_log.info(
                    "%s %s %d",
                    scope["method"],
                    scope.get("path", ""),
                    status["code"],
                    extra={
                        "method": scope["method"],
                        "path": scope.get("path", ""),
                        "route": route,
                        "status": status["code"],
                        "duration_ms": round(dt * 1e3, 2),
                    },
                )
            REQUEST_ID.reset(t_rid)
            SESSION_ID.reset(t_sid)

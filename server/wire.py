"""The HTTP connection itself: time limits on incomplete requests, connections per client address.

uvicorn (h11) waits forever for the rest of a request: a client that sends headers with
``Content-Length: 100000`` and a few bytes of body holds its connection — and a file descriptor —
until it goes away; 1,100 of them exhausted the process's descriptors and locked every new
client out (issue #17). Neither can the ASGI app help: it is not called before the headers are
complete. :class:`GuardedH11Protocol` is uvicorn's h11 protocol with three bounds:

- ``POCKETRAY_REQUEST_IDLE_TIMEOUT_S``: the longest silence while a request's headers or body
  are arriving (from the accept, or from the first byte of a request on a kept-alive
  connection; an idle kept-alive connection between requests is uvicorn's
  ``timeout_keep_alive``, closed without an answer);
- ``POCKETRAY_HEADER_TIMEOUT_S``: the whole header block, however it trickles in;
- ``POCKETRAY_MAX_CONNECTIONS_PER_CLIENT`` open connections per client address (0: no cap).

A request over a time limit is answered ``408`` (``{"detail"}``, ``Connection: close``) and the
connection closed — unless its answer has started, then it is only closed. While the app has not
read the body it was sent (uvicorn stops reading past 64 KiB until it does, e.g. while the
request waits for a slot of the body parsers), the silence is the service's, not the client's,
and does not count. A connection over the cap is answered ``429`` and closed at once.

Behind a reverse proxy every connection comes from the proxy's address: set
``POCKETRAY_MAX_CONNECTIONS_PER_CLIENT=0`` (or above the proxy's pool) and let the proxy bound
clients and their timeouts (nginx: ``limit_conn``, ``client_header_timeout``,
``client_body_timeout``; docs/API.md, "Hardening").

``python -m server`` runs uvicorn with it (:func:`uvicorn_options`).
"""

from __future__ import annotations

import functools
import json
import logging
import time
import weakref
from collections import Counter
from typing import Any

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol

from .config import ServerConfig

log = logging.getLogger("pocketray.wire")

# Open connections per client address, per uvicorn server (its ServerState), so that several
# servers in one process (tests) count apart.
_OPEN: "weakref.WeakKeyDictionary[Any, Counter[str]]" = weakref.WeakKeyDictionary()


def _raw_answer(status: int, reason: str, detail: str, extra: list[tuple[str, str]] = ()) -> bytes:
    body = json.dumps({"detail": detail}).encode()
    head = [f"HTTP/1.1 {status} {reason}", "content-type: application/json", f"content-length: {len(body)}",
            "connection: close", *(f"{k}: {v}" for k, v in extra)]
    return ("\r\n".join(head) + "\r\n\r\n").encode() + body


class GuardedH11Protocol(H11Protocol):
    """uvicorn's h11 protocol with the module's bounds, read from ``settings`` (a subclass per
    ServerConfig: :func:`uvicorn_options`; uvicorn makes one protocol object per connection).
    The class itself (``pocketray serve``, whose workers are separate processes that import it)
    reads the POCKETRAY_* environment once per process."""

    settings: ServerConfig | None = None

    def __init__(self, config, server_state, app_state, _loop=None):
        super().__init__(config, server_state, app_state, _loop)
        settings = self.settings or _environment_config()
        self.idle_s = settings.request_idle_timeout_s
        self.header_s = settings.header_timeout_s
        self.per_client = settings.max_connections_per_client
        self._timer = None
        self._header_deadline: float | None = None
        self._host: str | None = None

    # ---- connections per client ---------------------------------------------------------------
    def connection_made(self, transport) -> None:
        super().connection_made(transport)
        host = self.client[0] if self.client else None
        counts = _OPEN.setdefault(self.server_state, Counter())
        if host is not None and self.per_client and counts[host] >= self.per_client:
            log.warning("%s: over %d connections from this address: 429", host, self.per_client)
            transport.write(_raw_answer(429, "Too Many Requests",
                                        f"too many connections from this address (at most {self.per_client}, "
                                        "POCKETRAY_MAX_CONNECTIONS_PER_CLIENT); reuse one", [("retry-after", "1")]))
            transport.close()
            return
        if host is not None:
            counts[host] += 1
            self._host = host
        self._header_deadline = time.monotonic() + self.header_s
        self._arm()

    def connection_lost(self, exc) -> None:
        self._disarm()
        if self._host is not None:
            counts = _OPEN.get(self.server_state)
            if counts is not None:
                counts[self._host] -= 1
                if counts[self._host] <= 0:
                    del counts[self._host]
            self._host = None
        super().connection_lost(exc)

    # ---- incomplete requests ------------------------------------------------------------------
    def data_received(self, data: bytes) -> None:
        if self._header_deadline is None and self.conn.their_state is h11.IDLE:
            self._header_deadline = time.monotonic() + self.header_s    # a new request starts
        super().data_received(data)
        self._arm()

    def on_response_complete(self) -> None:
        super().on_response_complete()
        self._header_deadline = None    # between requests: uvicorn's keep-alive timeout
        self._arm()

    def _waiting_for_client(self) -> bool:
        """A request has started and is not complete: its headers or its body are arriving."""
        state = self.conn.their_state
        if state is h11.SEND_BODY:
            return True
        return state is h11.IDLE and self._header_deadline is not None

    def _disarm(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def _arm(self) -> None:
        self._disarm()
        if self.transport is None or self.transport.is_closing() or not self._waiting_for_client():
            return
        delay = self.idle_s
        if self.conn.their_state is h11.IDLE and self._header_deadline is not None:
            delay = min(delay, max(0.0, self._header_deadline - time.monotonic()))
        self._timer = self.loop.call_later(delay, self._timed_out)

    def _timed_out(self) -> None:
        self._timer = None
        if self.transport.is_closing() or not self._waiting_for_client():
            return
        if self.flow.read_paused:          # the app has not read what came: the wait is ours
            self._arm()
            return
        headers = self.conn.their_state is h11.IDLE
        what = ("its headers did not arrive within the limit" if headers else
                f"its body stopped arriving for {self.idle_s:g} s")
        log.warning("%s: request timed out, %s: 408", self.client[0] if self.client else "?", what)
        cycle = self.cycle if not headers else None
        if cycle is None or not cycle.response_started:
            self.transport.write(_raw_answer(
                408, "Request Timeout",
                f"request timed out: {what} (POCKETRAY_REQUEST_IDLE_TIMEOUT_S = {self.idle_s:g} s, "
                f"POCKETRAY_HEADER_TIMEOUT_S = {self.header_s:g} s)"))
        if cycle is not None:              # the app stops reading and its answer goes nowhere
            cycle.disconnected = True
            cycle.message_event.set()
        self.transport.close()


@functools.lru_cache(maxsize=1)
def _environment_config() -> ServerConfig:
    return ServerConfig()


def uvicorn_options(config: ServerConfig) -> dict[str, Any]:
    """Keyword arguments of ``uvicorn.run``/``uvicorn.Config`` that install the guard for ``config``."""
    return {"http": type("GuardedH11Protocol", (GuardedH11Protocol,), {"settings": config})}

"""The connection itself: time limits on incomplete requests, on answers the client does not take,
on idle or flooding WebSockets; connections and unsent bytes per client address.

uvicorn (h11) waits forever for the rest of a request: a client that sends headers with
``Content-Length: 100000`` and a few bytes of body holds its connection — and a file descriptor —
until it goes away; 1,100 of them exhausted the process's descriptors and locked every new
client out. Neither can the ASGI app help: it is not called before the headers are
complete. :class:`GuardedH11Protocol` is uvicorn's h11 protocol with these bounds:

- ``POCKETRAY_REQUEST_IDLE_TIMEOUT_S``: the longest silence while a request's headers or body
  are arriving (from the accept, or from the first byte of a request on a kept-alive
  connection; an idle kept-alive connection between requests is uvicorn's
  ``timeout_keep_alive``, closed without an answer);
- ``POCKETRAY_HEADER_TIMEOUT_S``: the whole header block, however it trickles in;
- ``POCKETRAY_MAX_CONNECTIONS_PER_CLIENT`` open connections per client address (0: no cap);
- ``POCKETRAY_WRITE_TIMEOUT_S``: an answer the client does not take — less than 64 KiB of it
  in that time — is abandoned and the connection aborted, which frees its buffered bytes (a
  4096² ``normal`` ``npy`` frame is 192 MiB; a client that never read held it as long as it
  stayed connected) — with a TCP reset, so that the kernel drops its part too;
- ``POCKETRAY_MAX_UNSENT_BYTES_PER_CLIENT``: answer bytes of one address that its clients have
  not taken yet (the transports' write buffers of all its connections); past it, a new request
  from the address is answered ``429`` before the app sees it, and an answer that starts
  meanwhile is replaced by the ``429`` (its bytes dropped, not buffered).

A request over a time limit is answered ``408`` (``{"detail"}``, ``Connection: close``) and the
connection closed — unless its answer has started, then it is only closed. While the app has not
read the body it was sent (uvicorn stops reading past 64 KiB until it does, e.g. while the
request waits for a slot of the body parsers), the silence is the service's, not the client's,
and does not count. A connection over the cap is answered ``429`` and closed at once.

A WebSocket upgrade hands the transport to :class:`GuardedWebSocketProtocol` (uvicorn's
websockets protocol): the request timers stop there — they would write a ``408`` into the
WebSocket stream — and the connection's place among its address's connections goes with it,
given back when the WebSocket closes. The WebSocket has its own bounds:

- ``POCKETRAY_WS_IDLE_TIMEOUT_S``: no message while the app waits for one: closed, code 1001;
- ``POCKETRAY_WS_MESSAGES_PER_S`` with a burst of ``POCKETRAY_WS_MESSAGE_BURST`` (a token
  bucket; pings count): a client over it is closed with 1008, its queued messages dropped and
  the rest of what it sent discarded unparsed (what arrives is parsed 4 KiB at a time, so a
  flood costs the event loop a few hundred frames, not all it sent);
- the write timeout and the unsent bytes above (:func:`refusal` tells the route).

Behind a reverse proxy every connection comes from the proxy's address: set
``POCKETRAY_MAX_CONNECTIONS_PER_CLIENT=0`` and ``POCKETRAY_MAX_UNSENT_BYTES_PER_CLIENT=0`` (or
above the proxy's pool) and let the proxy bound clients and their timeouts (nginx: ``limit_conn``,
``client_header_timeout``, ``client_body_timeout``, ``send_timeout``; docs/API.md, "Hardening").

``pocketray serve`` (:mod:`server.tools.cli`) runs uvicorn with both protocols.
"""

from __future__ import annotations

import functools
import json
import logging
import socket
import struct
import time
import weakref
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol
from uvicorn.protocols.utils import ClientDisconnected
from uvicorn.protocols.websockets.websockets_sansio_impl import WebSocketsSansIOProtocol

from ..config import ServerConfig

log = logging.getLogger("pocketray.wire")

# The open connections of each client address, per uvicorn server (its ServerState), so that
# several servers in one process (tests) count apart. A connection is its protocol object: the
# h11 one, then the WebSocket one it hands over to.
_PEERS: weakref.WeakKeyDictionary[Any, dict[str, set[Any]]] = weakref.WeakKeyDictionary()

WRITE_PROGRESS = 64 * 1024  # bytes a client must take per write timeout while an answer waits for it
WS_FEED = 4096  # bytes of WebSocket input parsed at a time (a flood is refused between slices)
UNSENT_RETRY_AFTER_S = 1
EXTENSION = "pocketray.wire"  # the scope extension through which a WebSocket route asks for refusal()


def _raw_answer(status: int, reason: str, detail: str, extra: Sequence[tuple[str, str]] = ()) -> bytes:
    body = json.dumps({"detail": detail}).encode()
    head = [
        f"HTTP/1.1 {status} {reason}",
        "content-type: application/json",
        f"content-length: {len(body)}",
        "connection: close",
        *(f"{k}: {v}" for k, v in extra),
    ]
    return ("\r\n".join(head) + "\r\n\r\n").encode() + body


def _reset(transport) -> None:
    """Abort ``transport`` with a TCP reset: its buffer is dropped at once, and the kernel's too (a
    plain close would leave the socket's unsent bytes to the kernel, retrying a client that reads
    nothing), and the client learns that its answer was abandoned."""
    sock = transport.get_extra_info("socket")
    if sock is not None:
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        except OSError:
            pass
    transport.abort()


def _group(server_state: Any, host: str) -> set[Any]:
    return _PEERS.setdefault(server_state, {}).setdefault(host, set())


def _leave(server_state: Any, host: str, protocol: Any) -> None:
    peers = _PEERS.get(server_state)
    if peers is None or host not in peers:
        return
    peers[host].discard(protocol)
    if not peers[host]:
        del peers[host]


def unsent_bytes(server_state: Any, host: str) -> int:
    """Answer bytes that the connections of ``host`` hold in their write buffers (not taken yet)."""
    peers = _PEERS.get(server_state, {})
    total = 0
    for protocol in peers.get(host, ()):
        transport = protocol.transport
        if transport is not None:
            total += transport.get_write_buffer_size()
    return total


def _unsent_detail(unsent: int, cap: int) -> str:
    return (
        f"too many answer bytes not taken by this address: {unsent / 2**20:.1f} MiB (at most "
        f"{cap / 2**20:g} MiB, POCKETRAY_MAX_UNSENT_BYTES_PER_CLIENT); read the answers you asked for first"
    )


def refusal(scope: Mapping[str, Any]) -> dict[str, Any] | None:
    """For a WebSocket route: the error message to answer instead of a frame while the client's
    address has more unsent bytes than allowed (``{"status": 429, "detail", "retry_after"}``),
    else None (also under a server without this module's protocols)."""
    check = scope.get("extensions", {}).get(EXTENSION, {}).get("refusal")
    return check() if check is not None else None


if TYPE_CHECKING:
    import asyncio

    _ProtocolBase = asyncio.Protocol  # what the mixin is mixed into: uvicorn's protocols
else:
    _ProtocolBase = object


class _Guard(_ProtocolBase):
    """What both protocols share: their place among their address's connections, the write watch.

    ``pause_writing``/``resume_writing`` are the transport's flow control (above 64 KiB
    buffered / below 16 KiB): while writing is paused the client must take ``WRITE_PROGRESS``
    bytes per ``write_s``, or the transport is aborted — ``abort`` drops the buffer at once,
    where ``close`` would keep it until the client takes it, i.e. forever."""

    # The protocol's own, set by uvicorn's protocol classes.
    transport: asyncio.Transport
    loop: asyncio.AbstractEventLoop

    def _guard_setup(self, settings: ServerConfig, server_state: Any) -> None:
        self.guard_state = server_state
        self.write_s = settings.write_timeout_s
        self.unsent_cap = settings.max_unsent_bytes_per_client
        self._host: str | None = None
        self._write_timer: asyncio.TimerHandle | None = None
        self._write_mark = 0

    def pause_writing(self) -> None:
        super().pause_writing()
        if self._write_timer is None:
            self._write_mark = self.transport.get_write_buffer_size()
            self._write_timer = self.loop.call_later(self.write_s, self._write_check)

    def resume_writing(self) -> None:
        super().resume_writing()
        self._write_unwatch()

    def _write_unwatch(self) -> None:
        if self._write_timer is not None:
            self._write_timer.cancel()
            self._write_timer = None

    def _write_check(self) -> None:
        self._write_timer = None
        size = self.transport.get_write_buffer_size()
        if size == 0:
            return
        if self._write_mark - size >= min(WRITE_PROGRESS, self._write_mark):  # slow, but taking
            self._write_mark = size
            self._write_timer = self.loop.call_later(self.write_s, self._write_check)
            return
        log.warning(
            "%s: the client took %d of %d answer bytes in %g s: connection aborted (POCKETRAY_WRITE_TIMEOUT_S)",
            self._host or "?",
            max(0, self._write_mark - size),
            self._write_mark,
            self.write_s,
        )
        self._write_abandoned()
        _reset(self.transport)

    def _write_abandoned(self) -> None:
        """The answer is given up (before the transport is aborted)."""

    def _unsent_refusal(self) -> tuple[int, str] | None:
        """(unsent bytes, detail) while this connection's address is over its unsent bytes, else None."""
        if not self.unsent_cap or self._host is None:
            return None
        unsent = unsent_bytes(self.guard_state, self._host)
        if unsent <= self.unsent_cap:
            return None
        return unsent, _unsent_detail(unsent, self.unsent_cap)

    def _guard_lost(self) -> None:
        self._write_unwatch()
        if self._host is not None:
            _leave(self.guard_state, self._host, self)
            self._host = None


class GuardedH11Protocol(_Guard, H11Protocol):
    """uvicorn's h11 protocol with the module's bounds, read from ``settings`` (set by a subclass
    for one ServerConfig; uvicorn makes one protocol object per connection).
    The class itself (``pocketray serve``, whose workers are separate processes that import it)
    reads the POCKETRAY_* environment once per process."""

    settings: ServerConfig | None = None

    def __init__(self, config, server_state, app_state, _loop=None):
        super().__init__(config, server_state, app_state, _loop)
        settings = self.settings or _environment_config()
        self._guard_setup(settings, server_state)
        self.idle_s = settings.request_idle_timeout_s
        self.header_s = settings.header_timeout_s
        self.per_client = settings.max_connections_per_client
        self._timer = None
        self._header_deadline: float | None = None
        self._upgraded = False
        if self.unsent_cap:
            self.app = self._admitting(self.app)

    # ---- connections per client ---------------------------------------------------------------
    def connection_made(self, transport) -> None:
        super().connection_made(transport)
        host = self.client[0] if self.client else None
        if host is not None:
            group = _group(self.server_state, host)
            if self.per_client and len(group) >= self.per_client:
                log.warning("%s: over %d connections from this address: 429", host, self.per_client)
                transport.write(
                    _raw_answer(
                        429,
                        "Too Many Requests",
                        f"too many connections from this address (at most {self.per_client}, "
                        "POCKETRAY_MAX_CONNECTIONS_PER_CLIENT); reuse one",
                        [("retry-after", "1")],
                    )
                )
                transport.close()
                return
            group.add(self)
            self._host = host
        self._header_deadline = time.monotonic() + self.header_s
        self._arm()

    def connection_lost(self, exc) -> None:
        self._disarm()
        self._guard_lost()
        super().connection_lost(exc)

    def handle_websocket_upgrade(self, event: h11.Request) -> None:
        """The transport goes to the WebSocket protocol: the request timers stop here (they would
        write a 408 into its stream), and the connection's slot goes with it."""
        self._upgraded = True
        self._disarm()
        super().handle_websocket_upgrade(event)
        ws = self.transport.get_protocol()
        host, self._host = self._host, None
        if host is not None:
            _leave(self.server_state, host, self)
            if isinstance(ws, GuardedWebSocketProtocol) and not self.transport.is_closing():
                ws.adopt(host)
        self._write_unwatch()

    # ---- unsent bytes per client ----------------------------------------------------------------
    def _admitting(self, app):
        """``app`` behind the unsent-bytes cap: a request of an address over it is answered 429
        without calling the app; an answer that starts while the address is over it becomes the
        429 (its body dropped instead of buffered)."""

        async def admitted(scope, receive, send):
            if scope["type"] != "http":
                return await app(scope, receive, send)
            over = self._unsent_refusal()
            if over is not None:
                log.warning("%s: %d answer bytes not taken: 429", self._host, over[0])
                return await _send_429(send, over[1])
            replaced = False

            async def guarded_send(message):
                nonlocal replaced
                if message["type"] == "http.response.start":
                    over = self._unsent_refusal()
                    if over is not None:
                        log.warning("%s: %d answer bytes not taken: answer replaced by 429", self._host, over[0])
                        replaced = True
                        return await _send_429(send, over[1])
                elif replaced:
                    return None
                await send(message)

            return await app(scope, receive, guarded_send)

        return admitted

    def _write_abandoned(self) -> None:
        if self.cycle is not None and not self.cycle.response_complete:
            self.cycle.disconnected = True
            self.cycle.message_event.set()

    # ---- incomplete requests ------------------------------------------------------------------
    def data_received(self, data: bytes) -> None:
        if self._header_deadline is None and self.conn.their_state is h11.IDLE:
            self._header_deadline = time.monotonic() + self.header_s  # a new request starts
        super().data_received(data)
        self._arm()

    def on_response_complete(self) -> None:
        super().on_response_complete()
        self._header_deadline = None  # between requests: uvicorn's keep-alive timeout
        self._arm()

    def _waiting_for_client(self) -> bool:
        """A request has started and is not complete: its headers or its body are arriving."""
        if self._upgraded:
            return False
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
        if self.flow.read_paused:  # the app has not read what came: the wait is ours
            self._arm()
            return
        headers = self.conn.their_state is h11.IDLE
        what = (
            "its headers did not arrive within the limit"
            if headers
            else f"its body stopped arriving for {self.idle_s:g} s"
        )
        log.warning("%s: request timed out, %s: 408", self.client[0] if self.client else "?", what)
        cycle = self.cycle if not headers else None
        if cycle is None or not cycle.response_started:
            self.transport.write(
                _raw_answer(
                    408,
                    "Request Timeout",
                    f"request timed out: {what} (POCKETRAY_REQUEST_IDLE_TIMEOUT_S = {self.idle_s:g} s, "
                    f"POCKETRAY_HEADER_TIMEOUT_S = {self.header_s:g} s)",
                )
            )
        if cycle is not None:  # the app stops reading and its answer goes nowhere
            cycle.disconnected = True
            cycle.message_event.set()
        self.transport.close()


async def _send_429(send, detail: str) -> None:
    body = json.dumps({"detail": detail}).encode()
    await send(
        {
            "type": "http.response.start",
            "status": 429,
            "headers": [
                (b"content-type", b"application/json"),
                (b"content-length", str(len(body)).encode()),
                (b"retry-after", str(UNSENT_RETRY_AFTER_S).encode()),
            ],
        }
    )
    await send({"type": "http.response.body", "body": body, "more_body": False})


class GuardedWebSocketProtocol(_Guard, WebSocketsSansIOProtocol):
    """uvicorn's websockets (sans-I/O) protocol with the module's WebSocket bounds, read from
    ``settings`` as :class:`GuardedH11Protocol` reads them; it takes over the connection's slot
    from the h11 protocol that upgraded it (:meth:`adopt`)."""

    settings: ServerConfig | None = None

    def __init__(self, config, server_state, app_state, _loop=None):
        super().__init__(config, server_state, app_state, _loop)
        settings = self.settings or _environment_config()
        self._guard_setup(settings, server_state)
        self.ws_idle_s = settings.ws_idle_timeout_s
        self.rate = settings.ws_messages_per_s
        self.burst = settings.ws_message_burst
        self._tokens = float(self.burst)
        self._refilled = time.monotonic()
        self._last_activity = time.monotonic()
        self._receiving = False
        self._idle_timer = None
        self._closed_here = False  # this module closed it (idle, flood, write timeout)

    def adopt(self, host: str) -> None:
        """This connection counts for ``host`` from now on (until :meth:`connection_lost`)."""
        _group(self.guard_state, host).add(self)
        self._host = host

    def connection_lost(self, exc) -> None:
        self._guard_lost()
        if self._idle_timer is not None:
            self._idle_timer.cancel()
            self._idle_timer = None
        super().connection_lost(exc)

    # ---- input: a bounded slice at a time, a token per message -------------------------------------
    def data_received(self, data: bytes) -> None:
        for start in range(0, len(data), WS_FEED):
            if self._closed_here or self.transport.is_closing():
                return  # the rest is discarded unparsed
            super().data_received(data[start : start + WS_FEED])

    def _take_token(self) -> bool:
        now = time.monotonic()
        self._tokens = min(float(self.burst), self._tokens + (now - self._refilled) * self.rate)
        self._refilled = now
        if self._tokens < 1.0:
            return False
        self._tokens -= 1.0
        return True

    def _flooded(self) -> None:
        log.warning(
            "%s: WebSocket over %g messages/s (burst %d): closed 1008", self._host or "?", self.rate, self.burst
        )
        self._close(
            1008,
            f"over {self.rate:g} messages/s (POCKETRAY_WS_MESSAGES_PER_S, burst "
            f"POCKETRAY_WS_MESSAGE_BURST = {self.burst})",
            fail=True,
        )

    def send_receive_event_to_app(self) -> None:
        if not self.close_sent and not self._take_token():
            self.frames = []
            self._flooded()
            return
        self._last_activity = time.monotonic()
        super().send_receive_event_to_app()

    def handle_ping(self) -> None:
        if not self._take_token():
            self._flooded()
            return
        super().handle_ping()

    def _close(self, code: int, reason: str, fail: bool = False) -> None:
        """Close from here: the app's queued messages are dropped and it is told; ``fail``: at once,
        discarding what the client sends (else the closing handshake, as the app's own close)."""
        if self.close_sent or self.transport.is_closing():
            return
        self._closed_here = True
        while not self.queue.empty():
            self.queue.get_nowait()
        self.queue.put_nowait({"type": "websocket.disconnect", "code": code, "reason": reason})
        if fail:
            self.conn.fail(code, reason)
        else:
            self.conn.send_close(code, reason)
        self.transport.write(b"".join(self.conn.data_to_send()))
        self.close_sent = True
        if fail:
            self.transport.close()
            return
        if self.read_paused:
            self.read_paused = False
            self.transport.resume_reading()
        self.close_timer = self.loop.call_later(self.close_timeout, self.transport.close)

    # ---- idle ------------------------------------------------------------------------------------
    def handle_connect(self, event) -> None:
        super().handle_connect(event)
        if getattr(self, "scope", None) is not None:
            self.scope["extensions"][EXTENSION] = {"refusal": self._refusal_message}
            self._idle_timer = self.loop.call_later(self.ws_idle_s, self._idle_check)

    def _idle_check(self) -> None:
        self._idle_timer = None
        if self.close_sent or self.transport.is_closing():
            return
        left = self._last_activity + self.ws_idle_s - time.monotonic()
        if not self._receiving or not self.queue.empty() or left > 0:  # the service is at work, or not yet
            self._idle_timer = self.loop.call_later(
                max(left, 0.05) if self._receiving else self.ws_idle_s, self._idle_check
            )
            return
        log.info("%s: WebSocket idle for %g s: closed 1001", self._host or "?", self.ws_idle_s)
        self._close(1001, f"idle for {self.ws_idle_s:g} s (POCKETRAY_WS_IDLE_TIMEOUT_S)")

    async def receive(self):
        self._receiving = True
        try:
            return await super().receive()
        finally:
            self._receiving = False
            self._last_activity = time.monotonic()

    async def send(self, message) -> None:
        if self._closed_here and message["type"] in ("websocket.send", "websocket.close"):
            if message["type"] == "websocket.close":
                return
            raise ClientDisconnected()  # the route sees WebSocketDisconnect
        await super().send(message)
        if message["type"] == "websocket.send":
            self._last_activity = time.monotonic()

    # ---- output ------------------------------------------------------------------------------------
    def _write_abandoned(self) -> None:
        self._closed_here = True
        while not self.queue.empty():  # connection_lost tells the app; nothing before that
            self.queue.get_nowait()

    def _refusal_message(self) -> dict[str, Any] | None:
        over = self._unsent_refusal()
        if over is None:
            return None
        log.warning("%s: %d answer bytes not taken: WebSocket message refused 429", self._host, over[0])
        return {"status": 429, "detail": over[1], "retry_after": UNSENT_RETRY_AFTER_S}


@functools.lru_cache(maxsize=1)
def _environment_config() -> ServerConfig:
    return ServerConfig()

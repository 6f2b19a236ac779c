"""WebSockets and slow readers against a real ``python -m server`` on loopback (server/http/wire.py).

1. a WebSocket that keeps talking is not cut by the request timers of its upgrade request (they
   wrote a 408 into the WebSocket stream: close 1002), and an idle one is closed with 1001;
2. a WebSocket gives back its connection slot when it closes (after POCKETRAY_MAX_CONNECTIONS_PER_CLIENT
   of them, every request of the address got 429 until a restart), and holds it while open;
3. a flood of tiny invalid messages is cut (1008) after the burst instead of answered one by
   one while ``/api/health`` waits;
4. an answer the client does not take is abandoned after POCKETRAY_WRITE_TIMEOUT_S and its bytes
   freed; while they are held, the address's new requests are answered 429.

No timing decides a test here except generous hang guards (the figures are bench/hostile.py's).
"""

from __future__ import annotations

import base64
import contextlib
import json
import os
import signal
import socket
import struct
import threading
import time

import httpx
import pytest
from pocketray_server_support import ServerProcess, new_session, server_env
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect as ws_connect

from tests.helpers import load_scaled, median_s

BIG_SIDE = 1024  # a 1024² normal npy frame: 12 MiB, more than loopback's socket buffers hold
WS_IDLE_S = 2.0
BURST = 40


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """One server with short wire limits for the tests below (each closes what it opened)."""
    tmp = tmp_path_factory.mktemp("wire_ws")
    env = server_env(
        tmp / "sessions.sqlite3",
        request_idle_timeout_s=1.0,
        header_timeout_s=2.0,
        max_connections_per_client=6,
        ws_idle_timeout_s=WS_IDLE_S,
        ws_messages_per_s=20,
        ws_message_burst=BURST,
        write_timeout_s=3.0,
        max_unsent_bytes_per_client=1 << 20,
        max_work=BIG_SIDE * BIG_SIDE,
        max_frame_cost=1e9,
    )
    proc = ServerProcess(env, tmp / "server.log").start()
    proc.wait_ready()
    try:
        yield proc
    finally:
        proc.kill(signal.SIGTERM)


@pytest.fixture(scope="module")
def sid(server) -> str:
    with httpx.Client(base_url=server.url, timeout=30) as c:
        return new_session(c)["id"]


def ws_url(server, sid: str) -> str:
    return f"ws://127.0.0.1:{server.port}/api/sessions/{sid}/ws"


def health_until(server, status: int, within_s: float) -> int:
    """Poll /api/health until it answers ``status`` (or the time is up); the last status."""
    deadline = time.monotonic() + within_s
    while True:
        code = httpx.get(server.url + "/api/health", timeout=10).status_code
        if code == status or time.monotonic() > deadline:
            return code
        time.sleep(0.1)


# ---- 1. timers through the upgrade ------------------------------------------------------------------------
def test_a_websocket_that_keeps_talking_outlives_the_request_timers(server, sid):
    """Rules out: cut after the request idle time (here 1 s; 5.1 s by default) with close 1002, the
    upgrade request's 408 written into the WebSocket stream."""
    answers = 0
    with ws_connect(ws_url(server, sid), open_timeout=10) as ws:
        t0 = time.monotonic()
        while time.monotonic() - t0 < 3.5:  # past the idle (1 s) and header (2 s) limits
            ws.send(json.dumps({"type": "pan", "dx": 1, "dy": 0, "frame": {"format": "png"}}))
            meta = json.loads(ws.recv(timeout=30))
            assert "version" in meta, meta
            assert ws.recv(timeout=30)[:4] == b"\x89PNG"
            answers += 1
            time.sleep(0.5)
    assert answers >= 5


def test_an_idle_websocket_is_closed_with_1001(server, sid):
    with ws_connect(ws_url(server, sid), open_timeout=10) as ws:
        ws.send(json.dumps({"type": "frame"}))
        ws.recv(timeout=30)
        ws.recv(timeout=30)
        t0 = time.monotonic()
        with pytest.raises(ConnectionClosed) as closed:
            ws.recv(timeout=WS_IDLE_S + 15)  # hang guard
        waited = time.monotonic() - t0
    assert closed.value.rcvd is not None and closed.value.rcvd.code == 1001, closed.value
    assert "POCKETRAY_WS_IDLE_TIMEOUT_S" in closed.value.rcvd.reason
    assert waited >= WS_IDLE_S * 0.9


# ---- 2. connection slots through the upgrade ---------------------------------------------------------------
def test_websockets_hold_their_connection_slot_while_open_and_give_it_back(server, sid):
    """Rules out: the slot was given back by the h11 protocol's connection_lost, which never runs after
    the upgrade: after 6 WebSockets (31 by default) every request of the address got 429."""
    for _ in range(10):  # more than the cap (6), one after the other
        with ws_connect(ws_url(server, sid), open_timeout=10) as ws:
            ws.send(json.dumps({"type": "frame"}))
            ws.recv(timeout=30)
            ws.recv(timeout=30)
    assert health_until(server, 200, within_s=5) == 200
    with contextlib.ExitStack() as held:
        for _ in range(6):
            held.enter_context(ws_connect(ws_url(server, sid), open_timeout=10))
        r = httpx.get(server.url + "/api/health", timeout=10)
        assert r.status_code == 429 and "POCKETRAY_MAX_CONNECTIONS_PER_CLIENT" in r.text, r.text
    assert health_until(server, 200, within_s=5) == 200


# ---- 3. floods -----------------------------------------------------------------------------------------------
def raw_websocket(server, sid: str, rcvbuf: int | None = None) -> socket.socket:
    """A WebSocket opened by hand (no extensions): the test writes frames as fast as it likes
    (``rcvbuf``: and takes next to nothing of what comes)."""
    sock = socket.socket()
    if rcvbuf is not None:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)  # before connect: no autotuning
    sock.settimeout(30)
    sock.connect(("127.0.0.1", server.port))
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(
        f"GET /api/sessions/{sid}/ws HTTP/1.1\r\nHost: t\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n".encode()
    )
    head = b""
    while b"\r\n\r\n" not in head:
        head += sock.recv(1)
    assert head.startswith(b"HTTP/1.1 101 "), head
    return sock


def masked_text(payload: bytes) -> bytes:
    mask = b"\x01\x02\x03\x04"
    size = bytes([0x80 | len(payload)]) if len(payload) < 126 else bytes([0x80 | 126]) + struct.pack("!H", len(payload))
    return bytes([0x81]) + size + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload))


def read_frames(sock: socket.socket, within_s: float) -> tuple[int, int | None]:
    """(text messages, close code or None) the server sends until it closes or ``within_s`` passes."""
    buf = b""
    texts, code = 0, None
    deadline = time.monotonic() + within_s
    sock.settimeout(1.0)
    while time.monotonic() < deadline:
        try:
            chunk = sock.recv(1 << 16)
        except TimeoutError:
            continue
        except ConnectionResetError:
            break
        if not chunk:
            break
        buf += chunk
        while len(buf) >= 2:
            opcode, n = buf[0] & 0x0F, buf[1] & 0x7F
            at = 2
            if n == 126:
                if len(buf) < 4:
                    break
                n, at = struct.unpack("!H", buf[2:4])[0], 4
            elif n == 127:
                if len(buf) < 10:
                    break
                n, at = struct.unpack("!Q", buf[2:10])[0], 10
            if len(buf) < at + n:
                break
            payload, buf = buf[at : at + n], buf[at + n :]
            if opcode == 0x1:
                texts += 1
            elif opcode == 0x8:
                code = struct.unpack("!H", payload[:2])[0] if len(payload) >= 2 else 1005
                return texts, code
    return texts, code


def test_a_flood_of_invalid_messages_is_cut_after_the_burst(server, sid):
    """Rules out: 20,000 tiny invalid messages in 0.1 s were each parsed and answered with a 422 while
    /api/health waited 2.4 s (9.1 s for 60,000)."""
    waits: list[float] = []
    stop = threading.Event()

    def poll() -> None:
        with httpx.Client(base_url=server.url, timeout=60) as c:
            while not stop.is_set():
                t0 = time.perf_counter()
                c.get("/api/health")
                waits.append(time.perf_counter() - t0)
                time.sleep(0.02)

    with httpx.Client(base_url=server.url, timeout=60) as c:
        health_s = median_s(lambda: c.get("/api/health"))
    sock = raw_websocket(server, sid)
    poller = threading.Thread(target=poll)
    poller.start()
    try:
        time.sleep(0.2)
        sock.sendall(masked_text(b"x") * 60_000)
        texts, code = read_frames(sock, within_s=30)
        time.sleep(0.3)
    finally:
        stop.set()
        poller.join()
        sock.close()
    assert code == 1008, (texts, code)
    assert texts <= BURST + 20, texts  # the burst (and what the rate refilled), not 60,000
    # hang guard: the event loop kept answering (2 s, or 20 health answers' time as loaded then)
    assert max(waits) < load_scaled(2.0, health_s, 20), (health_s, max(waits))
    assert health_until(server, 200, within_s=5) == 200


# ---- 4. answers the client does not take ------------------------------------------------------------------
def test_an_answer_not_taken_is_abandoned_and_its_bytes_freed(server, sid):
    """Rules out: a client that never read its frame held its bytes (a 4096² normal npy frame: ~360 MB)
    for as long as it stayed connected; ten such connections +5.97 GB."""
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # before connect: no autotuning
    sock.settimeout(30)
    sock.connect(("127.0.0.1", server.port))
    sock.sendall(
        f"GET /api/sessions/{sid}/frame?width={BIG_SIDE}&height={BIG_SIDE}&mode=normal&format=npy"
        f"&max_recursion_depth=1 HTTP/1.1\r\nHost: t\r\n\r\n".encode()
    )
    try:
        # While the frame waits in the server's buffer, the address gets no new answers ...
        assert health_until(server, 429, within_s=60) == 429
        r = httpx.get(server.url + "/api/health", timeout=10)
        assert (
            r.status_code == 429 and "POCKETRAY_MAX_UNSENT_BYTES_PER_CLIENT" in r.text and "retry-after" in r.headers
        ), r.text
        with ws_connect(ws_url(server, sid), open_timeout=10) as ws:  # nor its WebSocket messages
            ws.send(json.dumps({"type": "frame"}))
            refused = json.loads(ws.recv(timeout=30))
        assert refused["status"] == 429 and refused["retry_after"] >= 1, refused
        # ... and after the write timeout (3 s) the connection is reset and its bytes dropped.
        assert health_until(server, 200, within_s=15) == 200
        got, reset = 0, False
        try:
            while chunk := sock.recv(1 << 16):
                got += len(chunk)
        except ConnectionResetError:
            reset = True
        assert reset and got < BIG_SIDE * BIG_SIDE * 12, (reset, got)  # reset before the whole frame came
    finally:
        sock.close()


def test_a_websocket_frame_not_taken_is_abandoned_too(server, sid):
    sock = raw_websocket(server, sid, rcvbuf=4096)
    try:
        sock.sendall(
            masked_text(
                json.dumps(
                    {
                        "type": "frame",
                        "frame": {
                            "width": BIG_SIDE,
                            "height": BIG_SIDE,
                            "mode": "normal",
                            "format": "npy",
                            "max_recursion_depth": 1,
                        },
                    }
                ).encode()
            )
        )
        assert health_until(server, 429, within_s=60) == 429  # held ...
        assert health_until(server, 200, within_s=15) == 200  # ... then dropped
        got, reset = 0, False
        try:
            while chunk := sock.recv(1 << 16):
                got += len(chunk)
        except ConnectionResetError:
            reset = True
        assert reset and got < BIG_SIDE * BIG_SIDE * 12, (reset, got)
    finally:
        sock.close()


@pytest.fixture(scope="module")
def guarded(tmp_path_factory):
    """One server with short wire limits for the tests below (each closes what it opened)."""
    import signal

    from pocketray_server_support import ServerProcess, server_env

    tmp = tmp_path_factory.mktemp("guarded")
    env = server_env(
        tmp / "sessions.sqlite3", request_idle_timeout_s=1.0, header_timeout_s=2.0, max_connections_per_client=6
    )
    proc = ServerProcess(env, tmp / "server.log").start()
    try:
        yield proc
    finally:
        proc.kill(signal.SIGTERM)


def connect(server, timeout: float = 15.0) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", server.port), timeout=timeout)
    return sock


def read_all(sock: socket.socket) -> bytes:
    """Everything until the server closes (the socket timeout is the hang guard)."""
    out = b""
    while chunk := sock.recv(65536):
        out += chunk
    return out


def test_a_stalled_body_is_answered_408_and_closed(guarded):
    """Rules out: headers with Content-Length: 100000 and a few bytes held the connection forever."""
    sock = connect(guarded)
    sock.sendall(
        b"PUT /api/sessions/x/scene HTTP/1.1\r\nHost: t\r\ncontent-type: application/json\r\n"
        b'content-length: 100000\r\n\r\n{"materials"'
    )
    t0 = time.monotonic()
    answer = read_all(sock)
    assert answer.startswith(b"HTTP/1.1 408 "), answer[:200]
    assert b"connection: close" in answer.lower() and b"POCKETRAY_REQUEST_IDLE_TIMEOUT_S" in answer
    assert time.monotonic() - t0 < 30  # hang guard (the setting is 1 s), roomy for a loaded machine
    sock.close()


def test_headers_that_never_complete_are_answered_408(guarded):
    """A trickle of header bytes, each within the idle limit, runs into the header deadline."""
    sock = connect(guarded)
    sock.sendall(b"GET /api/health HTTP/1.1\r\nHost: t\r\n")
    got = b""
    sock.settimeout(0.5)
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline:
        try:
            sock.sendall(b"x")  # every 0.5 s: never idle for 1 s
            chunk = sock.recv(65536)
            if not chunk:
                break
            got += chunk
        except TimeoutError:
            continue
        except (BrokenPipeError, ConnectionResetError):
            break
    assert got.startswith(b"HTTP/1.1 408 "), got[:200]
    sock.close()
    silent = connect(guarded)  # a connection that sends nothing at all
    assert read_all(silent).startswith(b"HTTP/1.1 408 ")
    silent.close()


def test_slow_but_steady_requests_and_kept_alive_connections_are_not_cut(guarded):
    with httpx.Client(base_url=guarded.url, timeout=30) as c:
        sid = new_session(c)["id"]
        time.sleep(1.5)  # idle between requests: the keep-alive timeout's, not ours
        assert c.get(f"/api/sessions/{sid}").status_code == 200
    body = json.dumps({"type": "pinch", "scale": 2}).encode()
    sock = connect(guarded)
    sock.sendall(
        f"POST /api/sessions/{sid}/gesture HTTP/1.1\r\nHost: t\r\ncontent-type: application/json\r\n"
        f"content-length: {len(body)}\r\n\r\n".encode()
    )
    for i in range(0, len(body), 8):  # 8 bytes every 0.4 s: slower than a second in all
        sock.sendall(body[i : i + 8])
        time.sleep(0.4)
    answer = sock.recv(65536)
    assert answer.startswith(b"HTTP/1.1 200 "), answer[:300]
    sock.close()


def test_connections_per_client_address_are_bounded(guarded):
    """Rules out: 1,100 stalled connections exhausted the descriptors and locked every client out."""
    held = [connect(guarded) for _ in range(6)]
    extra = connect(guarded)
    answer = read_all(extra)
    assert answer.startswith(b"HTTP/1.1 429 ") and b"POCKETRAY_MAX_CONNECTIONS_PER_CLIENT" in answer, answer[:300]
    for sock in held:
        sock.close()
    deadline = time.monotonic() + 10
    while True:  # the server notices the closes: a client gets in again
        r = httpx.get(guarded.url + "/api/health", timeout=5)
        if r.status_code == 200 or time.monotonic() > deadline:
            break
        time.sleep(0.1)
    assert r.status_code == 200

"""Requests framed by both Content-Length and Transfer-Encoding (server/http/framing.py): answered
400 and their connection closed, so that the bytes after the chunks are never read as a request."""

from __future__ import annotations

import json
import socket

import httpx
import pytest

from server.http.framing import SingleFraming
from tests.helpers import run_coroutine

SMUGGLED = b"GET /api/smuggled HTTP/1.1\r\nHost: t\r\n\r\n"


def run(scope: dict) -> tuple[list[dict], bool]:
    """The messages SingleFraming sends for ``scope``, and whether it called the app behind it."""
    sent: list[dict] = []
    called = []

    async def app(scope, receive, send):
        called.append(scope)

    async def receive():
        return {"type": "http.request", "body": b"", "more_body": False}

    async def send(message):
        sent.append(message)

    run_coroutine(SingleFraming(app)(scope, receive, send))
    return sent, bool(called)


@pytest.mark.parametrize(
    ("headers", "refused"),
    [
        ([(b"content-length", b"44"), (b"transfer-encoding", b"chunked")], True),
        ([(b"Transfer-Encoding", b"chunked"), (b"Content-Length", b"0")], True),  # any case, any order
        ([(b"content-length", b"44")], False),
        ([(b"transfer-encoding", b"chunked")], False),
        ([], False),
    ],
)
def test_only_requests_framed_twice_are_refused(headers, refused):
    sent, called = run({"type": "http", "method": "POST", "path": "/api/sessions", "headers": headers})
    assert called is not refused
    if refused:
        start, body = sent
        assert start["status"] == 400 and (b"connection", b"close") in start["headers"]
        detail = json.loads(body["body"])["detail"]
        assert "Content-Length" in detail and "Transfer-Encoding" in detail


def test_a_websocket_upgrade_framed_twice_is_refused():
    headers = [(b"content-length", b"5"), (b"transfer-encoding", b"chunked")]
    sent, called = run({"type": "websocket", "path": "/api/sessions/x/ws", "headers": headers})
    assert not called and sent[0]["type"] == "websocket.close"


def test_the_bytes_after_the_chunks_are_not_answered_as_a_request(spawn_server):
    """Rules out: the POST was read by its (empty) chunked body, answered, and the connection kept open; the
    GET that a Content-Length-framing proxy took for its body was answered too (404)."""
    server = spawn_server()
    body = b"0\r\n\r\n" + SMUGGLED
    with socket.create_connection(("127.0.0.1", server.port), timeout=15) as sock:
        sock.sendall(
            b"POST /api/sessions HTTP/1.1\r\nHost: t\r\ncontent-type: application/json\r\n"
            b"content-length: %d\r\ntransfer-encoding: chunked\r\n\r\n" % len(body) + body
        )
        answer = b""
        while chunk := sock.recv(65536):  # until the server closes (the timeout is the hang guard)
            answer += chunk
    assert answer.startswith(b"HTTP/1.1 400 "), answer[:300]
    assert answer.count(b"HTTP/1.1 ") == 1 and b"connection: close" in answer.lower()
    assert httpx.get(server.url + "/api/health", timeout=10).status_code == 200  # the service is fine

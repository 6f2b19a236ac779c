"""The large-body slots against trickling clients (docs/API.md, "Hardening").

Was: eight connections trickling one byte every 4 s into 1 MB JSON bodies held all eight
large-body slots — each byte restarted the idle timer, and nothing bounded a body's total
time — so every honest JSON body over 64 KiB got 503 for as long as they trickled.

The requests here are driven through the app itself (httpx's ASGI transport in the app's
own event loop), which lets a test pick each request's client address and the pace of its
body bytes; the wire test at the end runs a real ``python -m server``.
"""

from __future__ import annotations

import asyncio
import json
import socket
import time
import warnings

import httpx
import pytest

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from pocketray_server_support import SMALL, make_config

from server.api.body import INLINE_BODY_BYTES, BodyParsers
from server.app import create_app

pytestmark = pytest.mark.gl  # the app's lifespan starts the GL worker

ATTACKER, HONEST = ("10.0.0.66", 40000), ("10.0.0.7", 40001)
DECLARED = 100_000  # over INLINE_BODY_BYTES: each such body takes a slot


def scene_body(min_bytes: int) -> bytes:
    """A valid session-create body of a scene larger than ``min_bytes``."""
    spheres = []
    body = b""
    while len(body) <= min_bytes:
        spheres += [
            {
                "center": [len(spheres) % 40 - 20, (len(spheres) // 40) % 40 - 20, -30 - len(spheres) // 1600],
                "radius": 0.2,
            }
            for _ in range(200)
        ]
        body = json.dumps({"scene": {"materials": [{}], "spheres": spheres}, "settings": SMALL}).encode()
    return body


HONEST_BODY = scene_body(INLINE_BODY_BYTES + 1024)
assert len(HONEST_BODY) > INLINE_BODY_BYTES


@pytest.fixture
def app_with(tmp_path):
    """factory(**settings) → (TestClient, app): an app with its lifespan run; closed at the end."""
    opened = []

    def make(**settings):
        c = TestClient(create_app(make_config(tmp_path, **settings)))
        c.__enter__()
        opened.append(c)
        return c

    yield make
    for c in opened:
        c.__exit__(None, None, None)


def run(c: TestClient, fn, *args):
    """``await fn(app, *args)`` in the app's own event loop (the TestClient's portal)."""
    return c.portal.call(fn, c.app, *args)


async def post(app, client: tuple[str, int], content, length: int | None = None) -> httpx.Response:
    headers = {"content-type": "application/json"}
    if length is not None:
        headers["content-length"] = str(length)
    transport = httpx.ASGITransport(app=app, client=client)
    async with httpx.AsyncClient(transport=transport, base_url="http://t", timeout=60) as h:
        return await h.post("/api/sessions", content=content, headers=headers)


async def trickle(gap_s: float, seconds: float):
    """One byte of the body every ``gap_s`` for at most ``seconds`` (then the body ends, short)."""
    t0 = time.monotonic()
    yield b'{"scene":'
    while time.monotonic() - t0 < seconds:
        await asyncio.sleep(gap_s)
        yield b" "


def slots_held(c: TestClient) -> int:
    return BodyParsers.of(type("R", (), {"app": c.app})())._in_flight


def test_trickling_bodies_from_one_address_leave_the_other_slots_to_other_clients(app_with):
    """Four trickling bodies from one address (four slots): it gets two (its share), the other
    two are answered 429 at once, and an honest large body from another address is served."""
    c = app_with(queue_size=4, body_slots_per_client=2, body_grace_s=60)

    async def scenario(app):
        tricklers = [asyncio.ensure_future(post(app, ATTACKER, trickle(0.2, 30), DECLARED)) for _ in range(4)]
        await asyncio.sleep(0.5)
        early = [t for t in tricklers if t.done()]
        t0 = time.monotonic()
        honest = await post(app, HONEST, HONEST_BODY)
        honest_s = time.monotonic() - t0
        for t in tricklers:
            t.cancel()
        await asyncio.gather(*tricklers, return_exceptions=True)
        return [t.result() for t in early], honest, honest_s

    early, honest, honest_s = run(c, scenario)
    assert len(early) == 2 and all(r.status_code == 429 for r in early), [(r.status_code, r.text) for r in early]
    r = early[0]
    assert "POCKETRAY_BODY_SLOTS_PER_CLIENT" in r.json()["detail"] and r.headers["retry-after"] == "1"
    assert honest.status_code == 201, honest.text[:300]  # was 503: every slot held by the trickles
    assert honest_s < 30
    assert slots_held(c) == 0


def test_a_body_below_the_minimum_rate_is_answered_408_and_its_slot_freed(app_with):
    c = app_with(queue_size=2, body_slots_per_client=0, body_grace_s=1.0, body_min_rate_bytes_s=64 * 1024)

    async def scenario(app):
        t0 = time.monotonic()
        # Was: no answer while the bytes kept coming (each within the idle timeout); bounded here by 20 s.
        r = await asyncio.wait_for(post(app, ATTACKER, trickle(0.2, 20), DECLARED), 25)
        return r, time.monotonic() - t0

    r, seconds = run(c, scenario)
    assert r.status_code == 408, r.text[:300]
    detail = r.json()["detail"]
    assert "POCKETRAY_BODY_MIN_RATE_BYTES_S" in detail and "POCKETRAY_BODY_GRACE_S" in detail, detail
    assert r.headers["connection"] == "close"
    assert seconds < 5, seconds  # the grace (1 s) and a little, not the 20 s of the trickle
    assert slots_held(c) == 0

    async def steady(app):  # a body that keeps up is read as before
        async def chunks():
            for i in range(0, len(HONEST_BODY), 16 * 1024):
                await asyncio.sleep(0.05)
                yield HONEST_BODY[i : i + 16 * 1024]

        return await post(app, HONEST, chunks(), len(HONEST_BODY))

    assert run(c, steady).status_code == 201


def test_the_slots_one_address_holds_are_counted_back_when_its_bodies_end(app_with):
    """The share is of bodies being read: one address sends any number of bodies in turn."""
    c = app_with(queue_size=2, body_slots_per_client=1)

    async def scenario(app):
        return [(await post(app, HONEST, HONEST_BODY)).status_code for _ in range(3)]

    assert run(c, scenario) == [201, 201, 201]
    assert slots_held(c) == 0


def test_a_trickled_body_is_closed_on_the_wire_with_its_408(spawn_server):
    server = spawn_server(body_grace_s=1.0, body_min_rate_bytes_s=64 * 1024, request_idle_timeout_s=30)
    sock = socket.create_connection(("127.0.0.1", server.port), timeout=15)
    sock.sendall(
        b"POST /api/sessions HTTP/1.1\r\nHost: t\r\ncontent-type: application/json\r\n"
        b"content-length: %d\r\n\r\n{" % DECLARED
    )
    t0 = time.monotonic()
    got = b""
    sock.settimeout(0.3)
    while time.monotonic() - t0 < 15:  # a byte every 0.3 s: never idle for the idle timeout
        try:
            sock.sendall(b" ")
            chunk = sock.recv(65536)
            if not chunk:
                break
            got += chunk
        except TimeoutError:
            continue
        except (BrokenPipeError, ConnectionResetError):
            break
    sock.close()
    assert got.startswith(b"HTTP/1.1 408 "), got[:300]
    assert b"POCKETRAY_BODY_MIN_RATE_BYTES_S" in got
    assert time.monotonic() - t0 < 10

"""The large-body slots against trickling clients (docs/API.md, "Hardening").

Rules out: eight connections trickling one byte every 4 s into 1 MB JSON bodies held all eight
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

import threading

from hypothesis import given, settings, strategies as st
from pocketray_server_support import SMALL, assert_422_listing, make_config, new_session, raw_json, state_of

from server.api.body import INLINE_BODY_BYTES, BodyParsers
from server.app import create_app
from tests.helpers import load_scaled, median_s

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
        # Rules out: no answer while the bytes kept coming (each within the idle timeout); bounded here by 20 s.
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


LOOSE = [
    ("post", "gesture", {"type": "pan", "dx": "1", "dy": 0}, "dx"),
    ("post", "gesture", {"type": "pan", "dx": True, "dy": 0}, "dx"),
    ("post", "gesture", {"type": "pinch", "scale": "2"}, "scale"),
    ("post", "gesture", {"type": "orbit", "yaw": 0, "pitch": False}, "pitch"),
    ("patch", "settings", {"width": "48"}, "width"),
    ("patch", "settings", {"width": 48.5}, "width"),
    ("patch", "settings", {"specialize": 1}, "specialize"),
    ("patch", "settings", {"samples_per_pixel": True}, "samples_per_pixel"),
    ("patch", "settings", {"update_threshold": False}, "update_threshold"),
    ("put", "camera", {"position": [True, 0, 100], "fov_y": 60}, "position"),
    ("put", "camera", {"fov_y": "60"}, "fov_y"),
]


PINCH = '{"type": "pinch", "scale": 2}'


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.floats(allow_nan=False) | st.text(alphabet='ab"\\[]{}\n/', max_size=6),
    lambda inner: (
        st.lists(inner, max_size=3) | st.dictionaries(st.text(alphabet='k"\\[]{', max_size=4), inner, max_size=3)
    ),
    max_leaves=20,
)


def nesting(value) -> int:
    if isinstance(value, dict):
        value = list(value.values())
    return 1 + max(map(nesting, value), default=0) if isinstance(value, list) else 0


@pytest.mark.parametrize("method,path,body,field", LOOSE)
def test_loose_types_are_refused_and_change_nothing(client, method, path, body, field):
    sid = new_session(client)["id"]
    before = state_of(client, sid)
    assert_422_listing(client.request(method.upper(), f"/api/sessions/{sid}/{path}", json=body), field)
    assert state_of(client, sid) == before


@pytest.mark.parametrize(
    "body,field",
    [
        ({"scenario": True, "n": 4}, "scenario"),
        ({"scenario": 1, "n": 4, "seed": True}, "seed"),
        ({"scenario": 1, "n": "4"}, "n"),
        ({"scenario": 1, "n": 4, "radius": "1"}, "radius"),
        ({"museum": {"n": 4, "kind": "rigid", "absent": "0.1"}}, "absent"),
    ],
)
def test_create_refuses_loose_types(client, body, field):
    assert_422_listing(client.post("/api/sessions", json=body), field)


def test_an_integer_is_what_json_schema_calls_one(client):
    """4.0 is an integer to JSON Schema (what the OpenAPI schema promises), 4.5 and true are not."""
    sid = new_session(client)["id"]
    r = client.patch(
        f"/api/sessions/{sid}/settings", json={"width": 32.0, "samples_per_pixel": 4.0, "max_prims": 6044511.0}
    )
    assert r.status_code == 200, r.text
    got = r.json()
    assert (got["width"], got["samples_per_pixel"], got["max_prims"]) == (32, 4, 6044511)
    assert all(type(got[k]) is int for k in ("width", "samples_per_pixel", "max_prims"))


def test_numbers_in_a_query_are_still_read_from_text(ready_client):
    c = ready_client
    sid = new_session(c)["id"]
    r = c.get(
        f"/api/sessions/{sid}/frame",
        params={"width": "32", "height": "48", "samples_per_pixel": "4", "specialize": "true"},
    )
    assert r.status_code == 200 and r.headers["content-type"] == "image/png", r.text
    assert_422_listing(c.get(f"/api/sessions/{sid}/frame", params={"samples_per_pixel": "2"}), "samples_per_pixel")


@pytest.mark.parametrize(
    "content,kind,words",
    [
        (PINCH.encode("utf-16"), "json_not_utf8", "not UTF-8"),
        (PINCH.encode("utf-16-le"), "json_invalid", "not valid JSON"),  # NUL bytes are no JSON
        (PINCH.encode("utf-32"), "json_not_utf8", "not UTF-8"),
        (b"\xef\xbb\xbf" + PINCH.encode(), "json_invalid", "byte-order mark"),
        (b'{"type": "pinch", "scale": 2, "scale": 0.5}', "json_duplicate_key", 'duplicate key "scale"'),
        (b'{"type": "pan", "dx": 1, "dy": 2, "viewport_height": {"a": 1, "a": 2}}', "json_duplicate_key", '"a"'),
        (("[" * 1000 + "]" * 1000).encode(), "json_too_deep", "nested deeper than 32"),
        (('{"a":' * 40 + "1" + "}" * 40).encode(), "json_too_deep", "nested deeper than 32"),
        (b'{"type": "pinch", "scale": ' + b"9" * 5000 + b"}", "json_invalid", "not a JSON value"),
        (b'{"type": "pinch", "scale": 2', "json_invalid", "not valid JSON"),
    ],
)
def test_bodies_that_are_not_strict_json_are_a_clear_422(client, content, kind, words):
    """Rules out: UTF-16 and duplicate keys taken silently, 1,000 levels "not valid UTF-8 JSON"."""
    sid = new_session(client)["id"]
    before = state_of(client, sid)
    r = client.post(f"/api/sessions/{sid}/gesture", **raw_json(content))
    assert r.status_code == 422, r.text
    (entry,) = r.json()["detail"]
    assert entry["type"] == kind and entry["loc"] == ["body"] and words in entry["msg"], entry
    assert state_of(client, sid) == before


@settings(max_examples=300, deadline=None)
@given(JSON_VALUES)
def test_the_depth_check_counts_what_the_parser_nests(value):
    """The depth is counted on the bytes (no regex: it held the GIL through a 16 MiB body); brackets
    and escaped quotes inside strings must not count."""
    from server.api.body import json_depth

    for text in (json.dumps(value), json.dumps(value, ensure_ascii=False), json.dumps(value, indent=1)):
        assert json_depth(text.encode()) == nesting(value), text


def test_a_large_body_is_read_as_strictly_as_a_small_one(client):
    """Bodies over the inline size go to the parser pool: the same rules hold there."""
    from server.api.body import INLINE_BODY_BYTES

    sid = new_session(client)["id"]
    spheres = ",".join('{"center": [' + str(i % 40) + ', 0, 0], "radius": 0.5}' for i in range(2200))
    text = '{"materials": [{}], "spheres": [' + spheres + '], "materials": [{}]}'
    assert INLINE_BODY_BYTES < len(text) < client.app.state.config.max_body_bytes
    r = client.put(f"/api/sessions/{sid}/scene", **raw_json(text))
    assert r.status_code == 422 and r.json()["detail"][0]["type"] == "json_duplicate_key", r.text


def test_large_bodies_are_parsed_on_the_pool_and_small_ones_inline(client, monkeypatch):
    import server.api.body as body

    threads: list[str] = []
    real = body.validate_body

    def spy(*args):
        threads.append(threading.current_thread().name)
        return real(*args)

    monkeypatch.setattr(body, "validate_body", spy)
    sid = new_session(client)["id"]
    threads.clear()
    scene = {"materials": [{}], "spheres": [{"center": [i % 40, 0, 0], "radius": 0.5} for i in range(2200)]}
    assert client.put(f"/api/sessions/{sid}/scene", json=scene).status_code == 200
    assert client.post(f"/api/sessions/{sid}/gesture", json={"type": "pinch", "scale": 2}).status_code == 200
    assert len(threads) == 2 and threads[0].startswith("pocketray-body"), threads
    assert threads[1] == threading.main_thread().name or not threads[1].startswith("pocketray-body"), threads


def test_health_answers_while_six_large_bodies_are_parsed(spawn_server):
    """Rules out: /api/health stalled while bodies are parsed (2.4 s behind one 16 MB scene, 15 s
    behind six). A hang guard only (2 s for six 4 MB bodies on a quiet machine, 20 health answers'
    time as the machine is loaded then); bench/hostile.py measures the latency with six maximum bodies."""
    s = spawn_server(
        max_body_bytes=16 << 20, max_spheres=1000, queue_size=8, body_slots_per_client=0
    )  # all six come from this one address
    with httpx.Client(base_url=s.url, timeout=60) as c:
        sid = new_session(c)["id"]
    sphere = '{"center": [1.5, -2.25, 3.125], "radius": 0.5, "material": 0}'
    body = ('{"materials": [{}], "spheres": [' + ",".join([sphere] * 65_000) + "]}").encode()  # 4 MB
    answers: list[int] = []

    def put() -> None:
        with httpx.Client(base_url=s.url, timeout=120) as c:
            answers.append(
                c.put(
                    f"/api/sessions/{sid}/scene", content=body, headers={"content-type": "application/json"}
                ).status_code
            )

    senders = [threading.Thread(target=put) for _ in range(6)]
    waits = []
    with httpx.Client(base_url=s.url, timeout=30) as c:
        health_s = median_s(lambda: c.get("/api/health"))
        for t in senders:
            t.start()
        while any(t.is_alive() for t in senders):
            t0 = time.perf_counter()
            assert c.get("/api/health").status_code == 200
            waits.append(time.perf_counter() - t0)
            time.sleep(0.02)
    for t in senders:
        t.join()
    assert answers == [422] * 6  # parsed and validated; then over max_spheres (1,000)
    assert len(waits) >= 3 and max(waits) < load_scaled(2.0, health_s, 20), (health_s, waits)

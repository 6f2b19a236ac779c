"""Issue #17: the service attacked — each defect the black-box attack found, reproduced.

1. a rejected (or failed, or timed-out) request changes nothing; 2. strict input; 3. bounded
memory (the 422 list, the render-target pool); 4. large bodies are parsed off the event loop;
5. incomplete requests are answered 408 and closed, connections per client are bounded (real
``python -m server`` processes: the guard is uvicorn's protocol); 6. store faults are 503 and
``/api/ready`` says so; 7. ``OPTIONS`` and 405 with the right ``Allow``.

No timing decides a test here except generous hang guards (the figures are bench/hostile.py's).
"""

from __future__ import annotations

import json
import math
import os
import socket
import sqlite3
import threading
import time
import warnings
from pathlib import Path

import httpx
import pytest
from hypothesis import given, settings, strategies as st

with warnings.catch_warnings():  # as in conftest.py: the TestClient still speaks httpx
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from pocketray_server_support import make_config, new_session

from server.app import create_app
from server.sessions.store import RedisStore, SessionState, SQLiteStore, StoreStartupError, StoreUnavailable

CONE_METHODS = ["bih", "bvh", "kdtree", "twolevel", "bruteforce", "auto"]


def state_of(c, sid: str) -> dict:
    return c.get(f"/api/sessions/{sid}").json()


def raw_json(text: str | bytes) -> dict:
    return {
        "content": text.encode() if isinstance(text, str) else text,
        "headers": {"content-type": "application/json"},
    }


def distance(camera: dict) -> float:
    return math.dist(camera["position"], camera["target"])


def assert_422(r, field: str, kind: str | None = None) -> list[dict]:
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert any(field in d["msg"] for d in detail), f"{field!r} not named in {detail}"
    if kind is not None:
        assert any(d["type"] == kind for d in detail), detail
    return detail


# ---- 1. validate everything, then commit once ------------------------------------------------------
@pytest.mark.parametrize("method", CONE_METHODS)
def test_a_refused_gesture_frame_moves_no_camera(client, method):
    """Was: 422 "mode 'cones' is not available with method 'bih'" after the pan was committed."""
    sid = new_session(client)["id"]
    before = state_of(client, sid)
    r = client.post(
        f"/api/sessions/{sid}/gesture",
        params={"frame": 1, "mode": "cones", "method": method},
        json={"type": "pan", "dx": 40, "dy": 0},
    )
    detail = assert_422(r, "mode")
    assert detail[0]["loc"] == ["query", "mode"] and "hre" in detail[0]["msg"]
    assert state_of(client, sid) == before  # version 1, camera where it was


def test_patch_and_create_refuse_a_mode_the_method_cannot_draw(client):
    """Was: accepted, and every later frame of the session failed."""
    sid = new_session(client)["id"]
    before = state_of(client, sid)
    assert_422(client.patch(f"/api/sessions/{sid}/settings", json={"mode": "cones"}), "mode")
    assert state_of(client, sid) == before
    assert_422(client.post("/api/sessions", json={"scenario": 3, "n": 16, "settings": {"mode": "cones"}}), "mode")
    # The combination that can draw cones is accepted.
    r = client.patch(f"/api/sessions/{sid}/settings", json={"method": "hre", "mode": "cones"})
    assert r.status_code == 200 and r.json()["version"] == before["version"] + 1, r.text


def test_a_timed_out_gesture_frame_retried_as_told_moves_the_camera_once(ready_client, monkeypatch):
    """Was: the 503 came after the gesture was committed, so the retry applied it twice."""
    c = ready_client
    service = c.app.state.service
    sid = new_session(c)["id"]
    before = state_of(c, sid)
    with monkeypatch.context() as m:
        m.setattr(service.config, "__dict__", {**service.config.__dict__, "render_timeout_s": 0.0})
        r = c.post(f"/api/sessions/{sid}/gesture?frame=1", json={"type": "pinch", "scale": 2})
    assert r.status_code == 503 and int(r.headers["retry-after"]) >= 1, r.text
    assert state_of(c, sid) == before
    r = c.post(f"/api/sessions/{sid}/gesture?frame=1", json={"type": "pinch", "scale": 2})  # the retry
    assert r.status_code == 200 and r.headers["x-session-version"] == str(before["version"] + 1), r.text
    after = state_of(c, sid)
    assert after["version"] == before["version"] + 1
    assert distance(after["camera"]) == pytest.approx(distance(before["camera"]) / 2)  # once, not /4


def test_a_gesture_frame_that_fails_on_the_gl_thread_changes_nothing(ready_client, monkeypatch):
    from server.frames.trace import GLNotReady

    c = ready_client
    frames = c.app.state.frames
    sid = new_session(c)["id"]
    before = state_of(c, sid)

    def lost(*args, **kwargs):
        raise GLNotReady("OpenGL context lost (test)")

    monkeypatch.setattr(frames, "wait", lost)
    r = c.post(f"/api/sessions/{sid}/gesture?frame=1", json={"type": "orbit", "yaw": 30})
    assert r.status_code == 503 and "retry-after" in r.headers, r.text
    assert state_of(c, sid) == before


# ---- 2. strict input -----------------------------------------------------------------------------------
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


@pytest.mark.parametrize("method,path,body,field", LOOSE)
def test_loose_types_are_refused_and_change_nothing(client, method, path, body, field):
    sid = new_session(client)["id"]
    before = state_of(client, sid)
    assert_422(client.request(method.upper(), f"/api/sessions/{sid}/{path}", json=body), field)
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
    assert_422(client.post("/api/sessions", json=body), field)


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
    assert_422(c.get(f"/api/sessions/{sid}/frame", params={"samples_per_pixel": "2"}), "samples_per_pixel")


PINCH = '{"type": "pinch", "scale": 2}'


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
    """Was: UTF-16 and duplicate keys taken silently, 1,000 levels "not valid UTF-8 JSON"."""
    sid = new_session(client)["id"]
    before = state_of(client, sid)
    r = client.post(f"/api/sessions/{sid}/gesture", **raw_json(content))
    assert r.status_code == 422, r.text
    (entry,) = r.json()["detail"]
    assert entry["type"] == kind and entry["loc"] == ["body"] and words in entry["msg"], entry
    assert state_of(client, sid) == before


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


def test_the_schema_of_samples_per_pixel_is_its_four_values(client):
    spec = client.get("/openapi.json").json()
    for path, method in (("/api/sessions/{session_id}/frame", "get"), ("/api/sessions/{session_id}/gesture", "post")):
        (param,) = [p for p in spec["paths"][path][method]["parameters"] if p["name"] == "samples_per_pixel"]
        assert [s.get("enum") for s in param["schema"]["anyOf"] if s.get("type") == "integer"] == [[1, 4, 9, 16]]


# ---- 3. bounded memory -------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def big_bodies(tmp_path_factory):
    """An app that takes bodies of the default size (16 MiB) and the default sphere cap."""
    from server.config import ServerConfig

    tmp = tmp_path_factory.mktemp("big")
    defaults = ServerConfig()
    with TestClient(
        create_app(
            make_config(tmp, max_body_bytes=defaults.max_body_bytes, max_spheres=defaults.max_spheres, warmup=False)
        )
    ) as c:
        yield c


def test_a_body_of_150000_bad_spheres_gets_a_short_422(big_bodies):
    """Was: a 72 MB 422 listing 450,000 errors (+840 MB resident)."""
    from server.api.schemas import MAX_LISTED_ERRORS

    bad = '{"center": [0, 0], "radius": -1, "material": -1}'  # three errors each
    body = '{"scene": {"materials": [{}], "spheres": [' + ",".join([bad] * 150_000) + "]}}"
    r = big_bodies.post("/api/sessions", **raw_json(body))
    assert r.status_code == 422
    assert len(r.content) < 16_000, len(r.content)
    detail = r.json()["detail"]
    assert len(detail) == MAX_LISTED_ERRORS + 1
    assert [d["loc"][:4] for d in detail[:3]] == [["body", "scene", "spheres", 0]] * 3
    assert detail[-1]["type"] == "too_many_errors" and "(450000 in all)" in detail[-1]["msg"], detail[-1]


def test_a_long_error_list_anywhere_is_cut_to_the_first_errors_and_a_count(client):
    from server.api.schemas import MAX_LISTED_ERRORS

    body = {"materials": [{"color": [2, 2, 2], "ambient": -1, "ior": 0}] * 40}  # 5 errors × 40
    r = client.post("/api/render", json={"scene": body})
    detail = r.json()["detail"]
    assert r.status_code == 422 and len(detail) == MAX_LISTED_ERRORS + 1
    assert detail[-1] == {
        "loc": ["body"],
        "msg": f"body: {200 - MAX_LISTED_ERRORS} more errors not listed (200 in all)",
        "type": "too_many_errors",
    }


def test_the_render_target_pool_is_bounded_in_bytes_not_entries(ready_client):
    """Was: up to 9 sizes with two RGBA32F targets each (frames at 11 sizes near 4096² left 5.3 GB).
    The 11-size sequence at small sizes on the GL thread: free targets never exceed the bound, busy
    ones are never taken away, and the service's pool has POCKETRAY_MAX_TARGET_BYTES as its bound."""
    from renderer.gl.targets import TargetPool

    worker, config = ready_client.app.state.worker, ready_client.app.state.config
    sizes = [(64 + 8 * i, 48 + 8 * i) for i in range(11)]
    bound = 3 * TargetPool.nbytes_of(*sizes[-1])

    def job(renderer):
        assert renderer.targets.max_bytes == config.max_target_bytes
        pool = TargetPool(renderer.ctx, bound)
        seen = []
        held = pool.acquire(*sizes[0])  # busy all along: never released by the pool
        for w, h in sizes:
            fbo = pool.acquire(w, h)
            pool.release(fbo)
            seen.append((pool.nbytes - pool.nbytes_of(*sizes[0]), len(pool.sizes)))
        again = pool.acquire(*sizes[-1])  # the most recent free size is reused
        reused = again.glo == fbo.glo
        pool.release(again)
        pool.release(held)
        total = pool.nbytes
        pool.clear()
        return seen, reused, total

    with worker.admit() as ticket:
        seen, reused, total = ticket.run(job, 30)
    assert all(free <= bound for free, _ in seen), seen
    # At the end the three largest (most recent) free sizes fill the bound, plus the busy one; on
    # the way the smaller sizes were kept as long as they fitted (up to 8 entries: bytes, not a count).
    assert seen[-1][1] == 4 and max(n for _, n in seen) > 4 and reused
    assert total <= bound + TargetPool.nbytes_of(*sizes[0])


# ---- 4. large bodies off the event loop ---------------------------------------------------------------------
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
    """Was: one 16 MB scene stalled /api/health 2.4 s, six 15 s. A hang guard only (2 s for six 4 MB
    bodies); bench/hostile.py measures the latency with six maximum bodies."""
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
    assert len(waits) >= 3 and max(waits) < 2.0, waits


# ---- 5. timeouts on the wire ------------------------------------------------------------------------------
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
    """Was: headers with Content-Length: 100000 and a few bytes held the connection forever."""
    sock = connect(guarded)
    sock.sendall(
        b"PUT /api/sessions/x/scene HTTP/1.1\r\nHost: t\r\ncontent-type: application/json\r\n"
        b'content-length: 100000\r\n\r\n{"materials"'
    )
    t0 = time.monotonic()
    answer = read_all(sock)
    assert answer.startswith(b"HTTP/1.1 408 "), answer[:200]
    assert b"connection: close" in answer.lower() and b"POCKETRAY_REQUEST_IDLE_TIMEOUT_S" in answer
    assert time.monotonic() - t0 < 10  # hang guard (the setting is 1 s)
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
    """Was: 1,100 stalled connections exhausted the descriptors and locked every client out."""
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


# ---- 6. truthful store health ----------------------------------------------------------------------------------
@pytest.fixture
def own_store(tmp_path):
    """An app on its own SQLite file (the tests below break it)."""
    with TestClient(create_app(make_config(tmp_path)), raise_server_exceptions=False) as c:
        yield c, tmp_path / "sessions.sqlite3"


def wait_ready_status(c, want: int) -> dict:
    deadline = time.monotonic() + 60
    while True:
        r = c.get("/api/ready")
        if r.status_code == want or time.monotonic() > deadline:
            return {"status": r.status_code, **r.json()}
        time.sleep(0.1)


def assert_store_503(r) -> None:
    assert r.status_code == 503 and r.headers.get("retry-after"), (r.status_code, r.text)
    detail = r.json()["detail"]
    assert detail.startswith("state: ") and "/" not in detail and "Traceback" not in detail, detail


def test_a_store_file_overwritten_with_junk_is_503_and_not_ready(own_store):
    """Was: 500 "DatabaseError", dropped connections, and /api/ready 200."""
    c, path = own_store
    assert wait_ready_status(c, 200)["status"] == 200
    sid = new_session(c)["id"]
    junk = os.urandom(path.stat().st_size)
    with open(path, "r+b") as f:  # the same file (inode), its bytes replaced
        f.write(junk)
    assert_store_503(c.post(f"/api/sessions/{sid}/gesture", json={"type": "pinch", "scale": 2}))
    assert_store_503(c.get(f"/api/sessions/{sid}"))
    ready = wait_ready_status(c, 503)
    assert ready["status"] == 503 and ready["detail"].startswith("state backend: sqlite"), ready


def test_a_deleted_store_file_refuses_writes_instead_of_losing_them(own_store):
    """Was: writes acknowledged after the file was deleted, gone at the restart."""
    c, path = own_store
    sid = new_session(c)["id"]
    for suffix in ("", "-wal", "-shm"):
        Path(str(path) + suffix).unlink(missing_ok=True)
    r = c.post(f"/api/sessions/{sid}/gesture", json={"type": "pinch", "scale": 2})
    assert_store_503(r)
    assert "deleted" in r.json()["detail"] and "restart" in r.json()["detail"]
    assert_store_503(c.post("/api/sessions", json={"scenario": 1, "n": 4}))
    ready = wait_ready_status(c, 503)
    assert ready["status"] == 503 and "deleted" in ready["detail"], ready


def test_a_corrupt_store_file_at_start_up_is_moved_aside_or_refused(tmp_path):
    """Was: the process exited (a traceback). Now a setting says which; neither loses the file."""
    path = tmp_path / "sessions.sqlite3"
    path.write_bytes(b"this is not a database, it is junk" * 100)
    with pytest.raises(StoreStartupError) as e:
        SQLiteStore(path, ttl_s=60, on_corrupt="refuse")
    assert "POCKETRAY_SQLITE_ON_CORRUPT=move_aside" in str(e.value) and "mv " in str(e.value)
    assert path.read_bytes().startswith(b"this is not")  # refused: untouched
    store = SQLiteStore(path, ttl_s=60, on_corrupt="move_aside")
    (aside,) = tmp_path.glob("sessions.sqlite3.corrupt-*")
    assert aside.read_bytes().startswith(b"this is not") and store.probe() is None
    store.create(
        SessionState(id="s", version=1, camera={}, home_camera={}, settings={}, scene_info={}, scene_rev="r"), b"x"
    )
    assert store.get("s").version == 1
    store.close()


def test_a_server_refusing_a_corrupt_store_says_how_to_recover(tmp_path):
    import subprocess
    import sys

    from pocketray_server_support import ROOT, server_env

    path = tmp_path / "sessions.sqlite3"
    path.write_bytes(b"junk" * 1000)
    env = server_env(path, sqlite_on_corrupt="refuse", warmup="false")
    done = subprocess.run(
        [sys.executable, "-m", "server"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=60
    )
    assert done.returncode != 0
    assert "is not a readable SQLite database" in done.stderr and "POCKETRAY_SQLITE_ON_CORRUPT" in done.stderr


def test_store_failures_of_every_kind_are_503_never_500(own_store, monkeypatch):
    c, _ = own_store
    store = c.app.state.store
    sid = new_session(c)["id"]
    for exc in (
        sqlite3.DatabaseError("file is not a database"),
        sqlite3.InterfaceError("bad binding"),
        StoreUnavailable("holding a session record that does not decode (JSONDecodeError)"),
    ):

        def broken(*args, exc=exc, **kwargs):
            raise exc

        monkeypatch.setattr(store, "get", broken)
        assert_store_503(c.get(f"/api/sessions/{sid}"))
    monkeypatch.undo()
    # A scene source the store holds that is no scene.
    c.app.state.service.cache.drop_session(sid)
    monkeypatch.setattr(store, "get_source", lambda session_id: ("rev", b"A" + b"not an npz"))
    assert_store_503(c.get(f"/api/sessions/{sid}/frame"))


def test_redis_change_retries_are_capped_and_end_in_503(redis_url):
    """Was: a WATCH conflict retried forever."""
    import redis

    store = RedisStore(redis_url, ttl_s=60, prefix=f"capped-{time.monotonic_ns()}:", max_retries=2)
    other = redis.Redis.from_url(redis_url)
    cam = {"position": [0, 0, 1], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 60}
    store.create(
        SessionState(id="s", version=1, camera=cam, home_camera=cam, settings={}, scene_info={}, scene_rev="r"), b"x"
    )
    attempts = []

    def collide(old):
        attempts.append(old.version)
        other.set(f"{store.prefix}state:s", store.client.get(f"{store.prefix}state:s"))  # another process wrote
        return old

    with pytest.raises(StoreUnavailable) as e:
        store.update("s", collide)
    assert len(attempts) == 3 and "busy" in str(e.value)
    assert store.get("s").version == 1
    other.close()
    store.close()


def test_a_redis_read_refreshes_the_ttl_in_one_command(redis_url):
    """Was: a MULTI/EXEC transaction (two PEXPIREs) per read past the touch interval."""
    import redis

    store = RedisStore(redis_url, ttl_s=3600, prefix=f"getex-{time.monotonic_ns()}:", touch_interval_s=60)
    cam = {"position": [0, 0, 1], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 60}
    store.create(
        SessionState(
            id="s", version=1, camera=cam, home_camera=cam, settings={}, scene_info={}, scene_rev="r", accessed_at=0.0
        ),
        b"x",
    )
    admin = redis.Redis.from_url(redis_url)
    k_state = f"{store.prefix}state:s"
    admin.pexpire(k_state, 5_000)

    def calls() -> dict[str, int]:
        stats = admin.info("commandstats")
        return {k.split("_", 1)[1]: v["calls"] for k, v in stats.items()}

    store.get("s")  # the first read also refreshes the scene key
    before = calls()
    for _ in range(5):
        assert store.get("s").version == 1
    after = calls()
    delta = {k: after.get(k, 0) - before.get(k, 0) for k in ("getex", "get", "multi", "exec", "pexpire")}
    assert delta == {"getex": 5, "get": 0, "multi": 0, "exec": 0, "pexpire": 0}, delta
    assert admin.pttl(k_state) > 3_000_000  # refreshed to the idle TTL (3600 s) by the read
    admin.close()
    store.close()


# ---- 7. HTTP basics -------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "path,allow",
    [
        ("/api/sessions", "OPTIONS, POST"),
        ("/api/sessions/abc", "DELETE, GET, OPTIONS"),
        ("/api/sessions/abc/scene", "GET, OPTIONS, PUT"),
        ("/api/sessions/abc/settings", "OPTIONS, PATCH"),
        ("/api/sessions/abc/gesture", "OPTIONS, POST"),
        ("/api/health", "GET, OPTIONS"),
    ],
)
def test_options_answers_the_paths_methods(client, path, allow):
    """Was: 405 with Allow: GET, HEAD (the static files' answer) on every API path."""
    r = client.options(path)
    assert r.status_code == 204 and r.headers["allow"] == allow and not r.content
    verbs = [m for m in ("GET", "POST", "PUT", "PATCH", "DELETE") if m not in allow]
    r = client.request(verbs[0], path)
    assert r.status_code == 405 and r.headers["allow"] == allow, r.text
    assert verbs[0] in r.json()["detail"] and allow in r.json()["detail"]


def test_error_bodies_stay_small_and_carry_no_paths(client):
    sid = new_session(client)["id"]
    answers = [
        client.post(f"/api/sessions/{sid}/gesture", **raw_json(b"[" * 5000)),
        client.post(f"/api/sessions/{sid}/gesture", **raw_json(b"\xff\xfe")),
        client.get("/api/sessions/no-such-session"),
        client.put("/api/sessions/x/scene", **raw_json(b'{"materials": [{"a": 1, "a": 2}]}')),
    ]
    for r in answers:
        assert 400 <= r.status_code < 500 and len(r.content) < 2_000, (r.status_code, len(r.content))
        assert "Traceback" not in r.text and str(Path(__file__).parents[2]) not in r.text

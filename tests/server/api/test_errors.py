"""The error table (server/api/errors.py): over HTTP and over the WebSocket, one answer.

Every row of the table is reached both ways — by an HTTP request and by the WebSocket
message that stands for it (a gesture message ⇔ ``POST …/gesture?frame=1`` with the
message's ``"frame"`` settings as the query; ``{"type": "frame"}`` ⇔ ``GET …/frame``) —
and both must pass through that row and answer alike: the same status, the same detail,
and ``retry_after`` exactly where HTTP sends ``Retry-After``, with the same seconds.
Rows no request reaches on its own (a store that stops answering, a render timing out,
a bug) are reached by making the service's frame call raise what they answer. Two rows only
HTTP reaches, checked over HTTP alone (``HTTP_ONLY`` says why): Starlette's own answers
(no such route) and a busy pool of body parsers.
"""

from __future__ import annotations

import json
import sqlite3
import warnings
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import pytest
import redis

with warnings.catch_warnings():  # as in conftest.py: the TestClient still speaks httpx
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from pathlib import Path

from pocketray_server_support import SMALL, make_config, new_session, raw_json

from renderer.geometry.scene import SceneError
from server.api import errors
from server.api.body import BodyParsers
from server.app import create_app
from server.faults import RenderTimeout, Superseded
from server.frames.trace import VariantsLimited
from server.sessions.ratelimit import RateLimited
from server.sessions.store import StoreFull

UNKNOWN_SESSION = "no-such-session"
PINCH = {"type": "pinch", "scale": 2}


@dataclass(frozen=True)
class Case:
    """One way into a row: a gesture (None: a frame without one) with frame settings, or a raw
    message/body; and what the service or the worker is made to do for it."""

    row: str
    status: int
    gesture: dict[str, Any] | None = None
    frame: dict[str, Any] = field(default_factory=dict)
    raw: str | bytes | None = None  # the message / body as sent, instead of gesture + frame
    session: str | None = None  # default: a live session
    raises: Exception | None = None  # service.frame_request raises this
    gl_error: str | None = None  # the GL context "failed" with this
    full_queue: bool = False  # every queue slot is taken
    path: str | None = None  # HTTP only: GET this path instead
    busy_bodies: bool = False  # HTTP only: every slot of the body parsers is taken
    busy_planning: bool = False  # every planning slot is taken


CASES = {
    "body field": Case("validation", 422, gesture={"type": "pinch", "scale": -1}),
    "query field": Case("validation", 422, gesture=PINCH, frame={"width": 0}),
    "query and body": Case("validation", 422, gesture={"type": "pan", "dx": 1}, frame={"tile_size": 1}),
    # in bounds (1 … 4096: the path integrator's counts) but not Whitted's set: the settings refuse it
    "samples_per_pixel not in the set": Case("scene", 422, frame={"samples_per_pixel": 3}),
    "not JSON": Case("validation", 422, raw="{nope"),
    "not an object": Case("validation", 422, raw="[1]"),
    "not UTF-8": Case("validation", 422, raw=b'{"type": "\xff"}'),
    "duplicate key": Case("validation", 422, raw='{"type": "pinch", "scale": 2, "scale": 3}'),
    "nested too deep": Case("validation", 422, raw="[" * 40 + "]" * 40),
    "work cap": Case("scene", 422, gesture=PINCH, frame={"width": 96, "height": 128, "max_recursion_depth": 4}),
    "renderer's SceneError": Case("scene", 422, raises=SceneError("camera.up", "parallel to the view")),
    "unknown session": Case("not_found", 404, session=UNKNOWN_SESSION),
    "queue full": Case("queue_full", 503, full_queue=True),
    "no GL context": Case("gl_unavailable", 503, gl_error="OpenGL unavailable: no EGL display (test)"),
    "render timed out": Case("timeout", 503, raises=RenderTimeout("render: not done within 120 s", 7)),
    "frame superseded": Case("superseded", 409, raises=Superseded("frame: stopped, superseded")),
    "sqlite locked": Case("store_unavailable", 503, raises=sqlite3.OperationalError("database is locked")),
    "redis gone": Case("store_unavailable", 503, raises=redis.ConnectionError("Connection refused")),
    "a bug": Case("internal", 500, raises=RuntimeError("a bug")),
    "store over its quota": Case("store_full", 507, raises=StoreFull(1000, 200, 1024)),
    "creation rate": Case("rate_limited", 429, raises=RateLimited(3, 60.0, 60)),
    "new variants rate": Case("variants_limited", 429, raises=VariantsLimited(2, 30.0, 30)),
    "no such route": Case("http_exception", 404, path="/api/no-such-route"),
    "planning slots taken": Case("busy", 503, gesture=PINCH, busy_planning=True),
    "body parsers busy": Case("busy", 503, busy_bodies=True),
}
RETRY_STATUSES = (429, 503, 507)  # the answers that say when to retry
HTTP_ONLY = {
    "no such route": "a WebSocket message has no route to miss",
    "body parsers busy": "messages are small and read by their connection, not by the pool for large bodies",
}


@pytest.fixture(scope="module")
def http(client) -> TestClient:
    """The same app, answering a bug with its 500 instead of raising it into the test."""
    return TestClient(client.app, raise_server_exceptions=False)


def over_http(http: TestClient, sid: str, case: Case):
    base = f"/api/sessions/{sid}"
    if case.path is not None:
        return http.get(case.path)
    if case.busy_bodies:  # a body over the inline size goes to the pool, whose slots are all taken
        scene = {"materials": [{}], "spheres": [{"center": [i % 50, 0, 0], "radius": 0.5} for i in range(2000)]}
        return http.put(f"{base}/scene", json=scene)
    if case.raw is not None:
        body = case.raw.encode() if isinstance(case.raw, str) else case.raw
        return http.post(
            f"{base}/gesture", params={"frame": 1}, content=body, headers={"content-type": "application/json"}
        )
    if case.gesture is None:
        return http.get(f"{base}/frame", params=case.frame)
    return http.post(f"{base}/gesture", params={"frame": 1, **case.frame}, json=case.gesture)


def over_ws(client: TestClient, sid: str, case: Case) -> dict[str, Any]:
    with client.websocket_connect(f"/api/sessions/{sid}/ws") as ws:
        if isinstance(case.raw, bytes):
            ws.send_bytes(case.raw)
        elif case.raw is not None:
            ws.send_text(case.raw)
        else:
            msg = dict(case.gesture or {"type": "frame"})
            if case.frame:
                msg["frame"] = case.frame
            ws.send_text(json.dumps(msg))
        return json.loads(ws.receive_text())


def test_every_row_of_the_table_is_checked():
    assert {c.row for c in CASES.values()} == {row.name for row in errors.ERROR_TABLE}


@pytest.mark.parametrize("name", list(CASES))
def test_http_and_websocket_answer_alike(client, http, sid, monkeypatch, name):
    case = CASES[name]
    service, frames, worker = client.app.state.service, client.app.state.frames, client.app.state.worker
    rows: list[str] = []
    answer = errors.answer

    def spy(exc, config, where):
        rows.append(errors.row_of(exc).name)
        return answer(exc, config, where)

    monkeypatch.setattr(errors, "answer", spy)
    if case.raises is not None:

        def frame_request(*args, **kwargs):
            raise case.raises

        monkeypatch.setattr(service, "frame_request", frame_request)
    if case.gl_error is not None:
        monkeypatch.setattr(worker, "error", case.gl_error)
    held = [worker.admit() for _ in range(worker.queue_size)] if case.full_queue else []
    parsers = BodyParsers.of(SimpleNamespace(app=client.app))
    bodies = [parsers.try_admit() for _ in range(parsers.admitted)] if case.busy_bodies else []
    planning = [frames._planning.acquire() for _ in range(frames.config.queue_size)] if case.busy_planning else []
    if planning:
        monkeypatch.setattr(frames, "PLAN_WAIT_S", 0.01)
    try:
        r = over_http(http, case.session or sid, case)
        http_rows, rows[:] = list(rows), []
        message = None if name in HTTP_ONLY else over_ws(client, case.session or sid, case)
    finally:
        for ticket in held:
            ticket.__exit__(None, None, None)
        for _ in bodies:
            parsers.release()
        for _ in planning:
            frames._planning.release()

    assert http_rows == [case.row] and rows == ([] if name in HTTP_ONLY else [case.row])  # through the one row
    assert r.status_code == case.status, r.text
    if name in HTTP_ONLY:
        assert ("retry-after" in r.headers) == (case.status in RETRY_STATUSES)
        return
    expected = {"status": r.status_code, "detail": r.json()["detail"]}
    if "retry-after" in r.headers:
        expected["retry_after"] = int(r.headers["retry-after"])
    assert ("retry-after" in r.headers) == (case.status in RETRY_STATUSES)
    assert message == expected


def test_validation_detail_names_query_and_body_fields_in_the_http_order(client, sid):
    """One 422 lists the frame settings' errors (as the query) before the gesture's (the body)."""
    case = CASES["query and body"]
    message = over_ws(client, sid, case)
    assert [d["loc"] for d in message["detail"]] == [["query", "tile_size"], ["body", "pan", "dy"]]
    assert all(d["msg"].startswith(("tile_size: ", "pan.dy: ")) for d in message["detail"])


def test_the_connection_stays_open_after_an_error(ready_client):
    c = ready_client
    sid = new_session(c)["id"]
    with c.websocket_connect(f"/api/sessions/{sid}/ws") as ws:
        ws.send_text("{nope")
        assert json.loads(ws.receive_text())["status"] == 422
        ws.send_text(json.dumps({"type": "frame", "frame": dict(SMALL, format="png")}))
        meta = json.loads(ws.receive_text())
        assert meta["version"] == 1 and meta["media_type"] == "image/png"
        assert ws.receive_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


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
    """Rules out: a 72 MB 422 listing 450,000 errors (+840 MB resident)."""
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

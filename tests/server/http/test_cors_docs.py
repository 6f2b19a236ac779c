"""Web basics (server/http/cors_docs.py): CORS from POCKETRAY_CORS_ORIGINS, plain OPTIONS with a correct
Allow header, /docs and /redoc without a CDN, readable operation ids and tags; format=exr; the
WebSocket route served by uvicorn over a real socket."""

from __future__ import annotations

import io
import json
import re
import warnings

import numpy as np
import pytest

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from pocketray_server_support import SMALL, make_config, new_session, wait_ready

from server.app import create_app
from server.frames.exr import decode_exr

ORIGIN = "http://phone.example:5173"


@pytest.fixture(scope="module")
def cors_client(tmp_path_factory):
    with TestClient(create_app(make_config(tmp_path_factory.mktemp("cors"), cors_origins=[ORIGIN]))) as c:
        wait_ready(c.get)
        yield c


def test_cors_allows_the_configured_origin_and_exposes_the_frame_headers(cors_client):
    sid = new_session(cors_client)["id"]
    r = cors_client.get(f"/api/sessions/{sid}/frame", headers={"Origin": ORIGIN})
    assert r.status_code == 200 and r.headers["access-control-allow-origin"] == ORIGIN
    exposed = {h.strip().lower() for h in r.headers["access-control-expose-headers"].split(",")}
    assert {"server-timing", "x-stats", "x-session-version", "x-method", "retry-after", "x-request-id"} <= exposed
    other = cors_client.get(f"/api/sessions/{sid}", headers={"Origin": "http://elsewhere.example"})
    assert other.status_code == 200 and "access-control-allow-origin" not in other.headers


def test_a_preflight_is_answered_for_the_origin_and_refused_for_others(cors_client):
    ask = {
        "Origin": ORIGIN,
        "Access-Control-Request-Method": "POST",
        "Access-Control-Request-Headers": "content-type, x-session-id",
    }
    r = cors_client.options("/api/sessions/abc/gesture", headers=ask)
    assert r.status_code == 200 and r.headers["access-control-allow-origin"] == ORIGIN
    assert "POST" in r.headers["access-control-allow-methods"]
    assert "x-session-id" in r.headers["access-control-allow-headers"].lower()
    assert cors_client.options("/api/render", headers={**ask, "Origin": "http://evil.example"}).status_code == 400


def test_no_cors_by_default(ready_client):
    r = ready_client.get("/api/info", headers={"Origin": ORIGIN})
    assert r.status_code == 200 and "access-control-allow-origin" not in r.headers


def allow(r) -> list[str]:
    return [m.strip() for m in r.headers["allow"].split(",")]


def test_plain_options_answers_204_with_the_paths_methods(ready_client):
    sid = new_session(ready_client)["id"]
    cases = {
        f"/api/sessions/{sid}": ["DELETE", "GET", "OPTIONS"],  # sorted (server/http/allow.py)
        "/api/sessions": ["OPTIONS", "POST"],
        f"/api/sessions/{sid}/scene": ["GET", "OPTIONS", "PUT"],
        f"/api/sessions/{sid}/frame": ["GET", "OPTIONS"],
        "/api/render": ["POST", "OPTIONS"],
        "/metrics": ["GET", "OPTIONS"],
        "/": ["GET", "HEAD", "OPTIONS"],
        "/js/api.js": ["GET", "HEAD", "OPTIONS"],
        "/shaders/raytrace.frag": ["GET", "HEAD", "OPTIONS"],
    }
    for path, methods in cases.items():
        r = ready_client.options(path)
        assert r.status_code == 204 and allow(r) == sorted(methods), (path, r.status_code, r.headers.get("allow"))
        for m in methods:  # what Allow says is what the path answers (no 405)
            if m not in ("OPTIONS", "DELETE"):
                assert ready_client.request(m, path).status_code != 405, (path, m)
    for path in ("/api/nothing-here", "/no-such-file.js"):
        assert ready_client.options(path).status_code == 404


def test_docs_and_redoc_load_everything_from_the_service_itself(ready_client):
    for path in ("/docs", "/redoc"):
        html = ready_client.get(path).text
        assert not re.search(r"(src|href)=[\"']?https?://", html), html
        assets = re.findall(r"[\"'](/docs-assets/[^\"']+)[\"']", html)
        assert assets
        for asset in assets:
            r = ready_client.get(asset)
            assert r.status_code == 200 and len(r.content) > 1000, asset


def test_openapi_operation_ids_are_the_route_names_grouped_by_tags(ready_client):
    doc = ready_client.get("/openapi.json").json()
    ops = {(path, method): op for path, item in doc["paths"].items() for method, op in item.items()}
    ids = [op["operationId"] for op in ops.values()]
    assert len(ids) == len(set(ids)) and all(re.fullmatch(r"[a-z][a-z_]*", i) for i in ids), ids
    assert ops[("/api/sessions", "post")]["operationId"] == "create_session"
    assert ops[("/api/sessions/{session_id}/frame", "get")]["operationId"] == "session_frame"
    assert ops[("/metrics", "get")]["tags"] == ["service"]
    tags = {t["name"] for t in doc["tags"]}
    assert tags == {"sessions", "frames", "device", "service"}
    assert all(len(op["tags"]) == 1 and op["tags"][0] in tags for op in ops.values())
    assert "exr" in doc["components"]["schemas"]["SettingsPatch"]["properties"]["format"]["anyOf"][0]["enum"]


def test_format_exr_holds_the_npy_arrays_as_float_channels(ready_client):
    sid = new_session(ready_client)["id"]
    for mode, channel in (("depth", "Z"), ("normal", "RGB"), ("primid", "id"), ("color", "RGB")):
        npy = np.load(
            io.BytesIO(ready_client.get(f"/api/sessions/{sid}/frame", params={"mode": mode, "format": "npy"}).content)
        )
        r = ready_client.get(f"/api/sessions/{sid}/frame", params={"mode": mode, "format": "exr"})
        assert r.status_code == 200 and r.headers["content-type"] == "image/x-exr"
        got = decode_exr(r.content)
        assert list(got) == [channel]
        arr = got[channel]
        if mode == "primid":
            assert np.array_equal(arr.view(np.int32), npy)
        elif mode == "color":  # linear floats: quantised they are the 8-bit frame
            assert arr.dtype == np.float32 and np.array_equal(np.floor(np.clip(arr, 0, 1) * 255 + 0.5), npy)
        else:
            assert np.array_equal(arr, npy)
    assert "exr" in ready_client.get("/api/info").json()["formats"]


def test_the_websocket_route_is_served_over_a_real_socket(spawn_server):
    from websockets.sync.client import connect

    s = spawn_server()
    s.wait_ready()
    import httpx

    with httpx.Client(base_url=s.url, timeout=30) as c:
        sid = new_session(c)["id"]
    with connect(f"ws://127.0.0.1:{s.port}/api/sessions/{sid}/ws", open_timeout=10) as ws:
        ws.send(json.dumps({"type": "pan", "dx": 5, "dy": 0, "frame": {"format": "npy", "mode": "primid"}}))
        meta = json.loads(ws.recv(timeout=60))
        frame = np.load(io.BytesIO(ws.recv(timeout=60)))
        assert meta["version"] == 2 and frame.shape == (SMALL["height"], SMALL["width"])
        ws.send(json.dumps({"type": "pinch", "scale": 0}))
        err = json.loads(ws.recv(timeout=60))
        assert err["status"] == 422 and "scale" in json.dumps(err["detail"])
        ws.send(json.dumps({"type": "frame"}))
        assert json.loads(ws.recv(timeout=60))["version"] == 2
        assert ws.recv(timeout=60)[:4] == b"\x89PNG"

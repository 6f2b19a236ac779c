"""Bad input: 422 naming the field (413 for oversized bodies), and nothing changes."""

from __future__ import annotations

import json

import pytest
from pocketray_server_support import new_session

from renderer.scenarios import scenario

GOOD_CAMERA = {"position": [0, 0, 100], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 60}


def scene_with(**camera) -> dict:
    s = scenario(1, 2, 0, 1.0).to_json()
    s["camera"] = {**GOOD_CAMERA, **camera}
    return s


def raw(text: str) -> dict:
    """A JSON body the way a careless client writes it (NaN / Infinity literals allowed)."""
    return {"content": text.encode(), "headers": {"content-type": "application/json"}}


def assert_422(r, field: str) -> None:
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    msgs = [d["msg"] for d in detail] if isinstance(detail, list) else [detail]
    assert any(field in m for m in msgs), f"{field!r} not named in {msgs}"
    if isinstance(detail, list):
        assert all({"loc", "msg", "type"} <= set(d) for d in detail)


def snapshot(client, sid: str) -> tuple:
    s = client.get(f"/api/sessions/{sid}").json()
    scene = client.get(f"/api/sessions/{sid}/scene").json()
    return s, scene


@pytest.fixture(scope="module")
def sid(client) -> str:
    return new_session(client)["id"]


CREATE_CASES = [
    ({"json": {"scenario": 3, "n": 10, "radius": 0}}, "radius"),
    ({"json": {"scenario": 3, "n": 10, "radius": -1}}, "radius"),
    (raw('{"scenario": 3, "n": 10, "radius": NaN}'), "radius"),
    (raw('{"scenario": 3, "n": 10, "radius": Infinity}'), "radius"),
    ({"json": {"scenario": 4, "n": 10}}, "scenario"),
    ({"json": {"scenario": 3}}, "n"),
    ({"json": {"scenario": 3, "n": 5000}}, "n"),  # over POCKETRAY_MAX_SPHERES of the test app
    ({"json": {"scenario": 3, "n": 1 << 22}}, "n"),  # over the absolute limit
    ({"json": {"scenario": 3, "n": -1}}, "n"),
    ({"json": {}}, "scenario"),
    ({"json": {"scenario": 1, "n": 2, "scene": scene_with()}}, "scenario"),
    ({"json": {"scene": scene_with(target=[0, 0, 100])}}, "camera.target"),
    ({"json": {"scene": scene_with(up=[0, 0, 0])}}, "camera.up"),
    ({"json": {"scene": scene_with(up=[0, 0, 5])}}, "camera.up"),
    ({"json": {"scene": scene_with(fov_y=180)}}, "fov_y"),
    ({"json": {"scene": scene_with(fov_y=0)}}, "fov_y"),
    ({"json": {"scene": {**scene_with(), "spheres": [{"center": [0, 0, 0], "radius": 0}]}}}, "radius"),
    ({"json": {"scene": {**scene_with(), "spheres": [{"center": [0, 0, 0], "radius": -2}]}}}, "radius"),
    (raw(json.dumps({"scene": scene_with()}).replace('"fov_y": 60', '"fov_y": NaN')), "fov_y"),
    (raw('{"scene": {"materials": [{}], "spheres": [{"center": [0, Infinity, 0], "radius": 1}]}}'), "center"),
    ({"json": {"scene": {**scene_with(), "spheres": [{"center": [0, 0, 0], "radius": 1, "material": 7}]}}}, "material"),
    ({"json": {"scene": {**scene_with(), "materials": []}}}, "materials"),
    ({"json": {"scenario": 1, "n": 2, "settings": {"width": 0}}}, "width"),
    ({"json": {"scenario": 1, "n": 2, "settings": {"height": 4097}}}, "height"),
    ({"json": {"scenario": 1, "n": 2, "settings": {"method": "no-such-method"}}}, "method"),
    ({"json": {"scenario": 1, "n": 2, "settings": {"mode": "xray"}}}, "mode"),
    (
        {"json": {"scenario": 1, "n": 2, "settings": {"width": 96, "height": 128, "max_recursion_depth": 8}}},
        "max_recursion_depth",
    ),
    ({"json": {"scenario": 1, "n": 2, "colour": "red"}}, "colour"),
]


@pytest.mark.parametrize("kw,field", CREATE_CASES)
def test_create_rejects(client, kw, field):
    assert_422(client.post("/api/sessions", **kw), field)


SESSION_CASES = [
    ("put", "camera", {"json": {**GOOD_CAMERA, "target": [0, 0, 100]}}, "target"),
    ("put", "camera", {"json": {**GOOD_CAMERA, "up": [0, 0, 0]}}, "up"),
    ("put", "camera", {"json": {**GOOD_CAMERA, "fov_y": 180}}, "fov_y"),
    ("put", "camera", {"json": {**GOOD_CAMERA, "fov_y": -1}}, "fov_y"),
    ("put", "camera", raw('{"position": [0, 0, NaN]}'), "position"),
    ("put", "camera", raw('{"target": [0, -Infinity, 0]}'), "target"),
    ("put", "camera", {"json": {**GOOD_CAMERA, "position": [0, 0]}}, "position"),
    ("put", "scene", {"json": {**scene_with(), "spheres": [{"center": [0, 0, 0], "radius": -1}]}}, "radius"),
    ("put", "scene", {"json": scene_with(target=[0, 0, 100])}, "camera.target"),
    ("patch", "settings", {"json": {"width": 0}}, "width"),
    ("patch", "settings", {"json": {"height": 5000}}, "height"),
    ("patch", "settings", {"json": {"method": "no-such-method"}}, "method"),
    ("patch", "settings", {"json": {"mode": "wire"}}, "mode"),
    ("patch", "settings", {"json": {"format": "gif"}}, "format"),
    ("patch", "settings", {"json": {"quality": 0}}, "quality"),
    ("patch", "settings", {"json": {"max_recursion_depth": 9}}, "max_recursion_depth"),
    ("patch", "settings", {"json": {"width": 96, "height": 128, "max_recursion_depth": 3}}, "max_recursion_depth"),
    ("patch", "settings", {"json": {"method": "rayengine", "mode": "cones"}}, "mode"),
    ("post", "gesture", {"json": {"type": "pinch", "scale": 0}}, "scale"),
    ("post", "gesture", {"json": {"type": "pinch", "scale": -2}}, "scale"),
    ("post", "gesture", raw('{"type": "pinch", "scale": NaN}'), "scale"),
    ("post", "gesture", raw('{"type": "pan", "dx": Infinity, "dy": 0}'), "dx"),
    ("post", "gesture", {"json": {"type": "pan", "dx": 1}}, "dy"),
    ("post", "gesture", {"json": {"type": "twist", "angle": 3}}, "type"),
    ("post", "gesture", {"json": {"type": "orbit", "yaw": 361, "pitch": 0}}, "yaw"),
    ("post", "gesture", {"json": {"type": "orbit", "yaw": 0, "pitch": -400}}, "pitch"),
    ("post", "gesture", raw('{"type": "orbit", "yaw": NaN, "pitch": 0}'), "yaw"),
    ("post", "gesture", raw('{"type": "orbit", "yaw": 0, "pitch": Infinity}'), "pitch"),
    ("post", "gesture", {"json": {"type": "orbit", "yaw": "left"}}, "yaw"),
    ("post", "gesture?frame=1&width=0", {"json": {"type": "pinch", "scale": 2}}, "width"),
    (
        "post",
        "gesture?frame=1&width=96&height=128&max_recursion_depth=4",
        {"json": {"type": "pinch", "scale": 2}},
        "max_recursion_depth",
    ),
    ("post", "gesture?frame=1&method=nope", {"json": {"type": "reset"}}, "method"),
    ("get", "frame?width=4097", {}, "width"),
    ("get", "frame?height=0", {}, "height"),
    ("get", "frame?method=nope", {}, "method"),
    ("get", "frame?mode=nope", {}, "mode"),
    ("get", "frame?format=gif", {}, "format"),
    ("get", "frame?width=96&height=128&max_recursion_depth=8", {}, "max_recursion_depth"),
    ("get", "stats?max_prims=0", {}, "max_prims"),
]


@pytest.mark.parametrize("method,path,kw,field", SESSION_CASES)
def test_session_change_rejected_changes_nothing(client, sid, method, path, kw, field):
    before = snapshot(client, sid)
    r = client.request(method.upper(), f"/api/sessions/{sid}/{path}", **kw)
    assert_422(r, field)
    assert snapshot(client, sid) == before


def test_pan_out_of_range_is_422_and_changes_nothing(client):
    sid = new_session(client)["id"]
    client.put(
        f"/api/sessions/{sid}/camera", json={**GOOD_CAMERA, "position": [9.99e6, 0, 100], "target": [9.99e6, 0, 0]}
    )
    before = snapshot(client, sid)
    r = client.post(f"/api/sessions/{sid}/gesture", json={"type": "pan", "dx": -1e6, "dy": 0})
    assert_422(r, "dx")
    assert snapshot(client, sid) == before


@pytest.mark.parametrize(
    "settings,field",
    [
        ({"width": 0}, "width"),
        ({"width": 4097}, "width"),
        ({"method": "x"}, "method"),
        ({"mode": "x"}, "mode"),
        ({"width": 96, "height": 128, "max_recursion_depth": 3}, "max_recursion_depth"),
    ],
)
def test_stateless_render_rejects(client, settings, field):
    assert_422(client.post("/api/render", json={"scene": scene_with(), "settings": settings}), field)


def test_stateless_render_rejects_bad_scene(client):
    assert_422(client.post("/api/render", json={"scene": scene_with(up=[0, 0, 0])}), "camera.up")
    assert_422(client.post("/api/render", **raw('{"scene": {"materials": [{"ior": NaN}]}}')), "ior")


def test_oversized_body_is_413_and_changes_nothing(client, sid):
    before = snapshot(client, sid)
    big = scene_with()
    big["spheres"] = [{"center": [i % 20, 0, 0], "radius": 0.5} for i in range(10000)]  # > 256 KiB
    r = client.put(f"/api/sessions/{sid}/scene", json=big)
    assert r.status_code == 413 and "body" in r.json()["detail"]
    # chunked (no Content-Length) is refused as well
    body = json.dumps(big).encode()
    r = client.put(
        f"/api/sessions/{sid}/scene",
        content=iter([body[:1000], body[1000:]]),
        headers={"content-type": "application/json"},
    )
    assert r.status_code == 413
    assert snapshot(client, sid) == before


def test_method_limits_are_checked_before_a_gesture_is_applied(client, sid):
    """A method's own limits (here: mode 'cones' needs method 'hre') are a 422 up front."""
    from renderer.settings import METHOD_NAMES

    if "rayengine" not in METHOD_NAMES:
        return  # nothing to check with this renderer
    before = snapshot(client, sid)
    r = client.post(
        f"/api/sessions/{sid}/gesture?frame=1&method=rayengine&mode=cones", json={"type": "pinch", "scale": 2}
    )
    assert_422(r, "mode")
    assert snapshot(client, sid) == before

"""The session routes (server/api/routes/sessions.py): create, read, change, delete; bad input is
422 naming the field, and a refusal changes nothing."""

from __future__ import annotations

import json

import pytest
from pocketray_server_support import (
    GOOD_CAMERA,
    SMALL,
    assert_422,
    assert_422_listing,
    new_session,
    raw,
    scene_with,
    small_scene_json,
    snapshot,
    state_of,
)

from renderer.scenarios import scenario
from renderer.settings import SETTINGS

SESSION_KEYS = {"id", "version", "settings", "scene_info", "camera"}


# A session's settings are exactly the declared ones (renderer.settings.SETTINGS).
SETTING_KEYS = {s.name for s in SETTINGS}


def test_create_from_scenario_and_read(client):
    s = new_session(client, n=100, seed=7, radius=0.5)
    assert set(s) >= SESSION_KEYS
    assert len(s["id"]) >= 32  # token_urlsafe(24): 192 random bits
    assert s["version"] == 1
    assert set(s["settings"]) == SETTING_KEYS
    assert s["settings"]["width"] == SMALL["width"]
    assert s["scene_info"] == {
        "n_spheres": 100,
        "n_planes": 1,
        "scenario": 3,
        "n": 100,
        "seed": 7,
        "radius": 0.5,
        "animated": False,
        "n_moving": 0,
        "museum": None,
        "mesh_scene": None,
        "n_meshes": 0,
        "n_triangles": 0,
        "n_degenerate_triangles": 0,
        "n_moving_meshes": 0,
    }
    got = client.get(f"/api/sessions/{s['id']}").json()
    assert got["camera"] == {
        "position": [0.0, 0.0, 100.0],
        "target": [0.0, 0.0, 0.0],
        "up": [0.0, 1.0, 0.0],
        "fov_y": 60.0,
    }
    assert {k: got[k] for k in ("id", "version", "settings", "scene_info")} == {
        k: s[k] for k in ("id", "version", "settings", "scene_info")
    }
    scene = client.get(f"/api/sessions/{s['id']}/scene").json()
    assert len(scene["spheres"]) == 100 and scene["spheres"] == scenario(3, 100, 7, 0.5).to_json()["spheres"]


def test_create_from_scene_with_settings(client):
    scene = small_scene_json(8)
    scene["camera"] = {"position": [5, 5, 60], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 50}
    r = client.post("/api/sessions", json={"scene": scene, "settings": {"width": 32, "format": "jpeg", "quality": 70}})
    assert r.status_code == 201, r.text
    s = r.json()
    assert s["scene_info"]["n_spheres"] == 8 and s["scene_info"].get("scenario") is None
    assert s["settings"]["width"] == 32 and s["settings"]["format"] == "jpeg" and s["settings"]["quality"] == 70
    assert s["camera"]["position"] == [5.0, 5.0, 60.0]
    back = client.get(f"/api/sessions/{s['id']}/scene").json()
    assert back["spheres"] == scenario(1, 8, 0, 1.0).to_json()["spheres"]
    assert back["camera"]["fov_y"] == 50.0


def test_scene_put_camera_put_settings_patch_bump_version(client):
    s = new_session(client)
    sid = s["id"]
    scene = small_scene_json(4)
    r = client.put(f"/api/sessions/{sid}/scene", json=scene)
    assert r.json() == {"version": 2}
    assert len(client.get(f"/api/sessions/{sid}/scene").json()["spheres"]) == 4
    cam = {"position": [1.0, 2.0, 30.0], "target": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov_y": 40.0}
    r = client.put(f"/api/sessions/{sid}/camera", json=cam)
    assert r.json() == {"version": 3, "camera": cam}
    r = client.patch(f"/api/sessions/{sid}/settings", json={"mode": "depth", "max_prims": 4})
    body = r.json()
    assert body["version"] == 4 and body["mode"] == "depth" and body["max_prims"] == 4
    assert set(body) == SETTING_KEYS | {"version"}
    got = client.get(f"/api/sessions/{sid}").json()
    assert got["version"] == 4 and got["camera"] == cam and got["settings"]["mode"] == "depth"
    assert got["scene_info"]["n_spheres"] == 4


def test_isolation_between_sessions(client):
    a = new_session(client)
    b = new_session(client, scenario=1, n=27)
    assert a["id"] != b["id"]
    client.post(f"/api/sessions/{a['id']}/gesture", json={"type": "pinch", "scale": 2})
    client.patch(f"/api/sessions/{a['id']}/settings", json={"mode": "normal"})
    client.put(f"/api/sessions/{a['id']}/scene", json=small_scene_json(2))
    got_b = client.get(f"/api/sessions/{b['id']}").json()
    assert got_b["version"] == 1 and got_b["camera"]["position"] == [0.0, 0.0, 100.0]
    assert got_b["settings"]["mode"] == "color" and got_b["scene_info"]["n_spheres"] == 27
    assert len(client.get(f"/api/sessions/{b['id']}/scene").json()["spheres"]) == 27
    assert client.delete(f"/api/sessions/{a['id']}").status_code == 204
    assert client.get(f"/api/sessions/{b['id']}").status_code == 200


@pytest.mark.parametrize(
    "method,path",
    [
        ("get", ""),
        ("get", "/scene"),
        ("put", "/scene"),
        ("put", "/camera"),
        ("patch", "/settings"),
        ("post", "/gesture"),
        ("get", "/frame"),
        ("get", "/stats"),
        ("delete", ""),
    ],
)
def test_unknown_session_is_404(client, method, path):
    bodies = {
        "/scene": small_scene_json(1),
        "/camera": {"position": [0, 0, 5]},
        "/settings": {"width": 8},
        "/gesture": {"type": "reset"},
    }
    kw = {"json": bodies[path]} if method in ("put", "patch", "post") else {}
    r = client.request(method.upper(), f"/api/sessions/doesNotExist123/{path.lstrip('/')}".rstrip("/"), **kw)
    assert r.status_code == 404
    assert "session" in r.json()["detail"]


def test_deleted_session_is_gone(client):
    sid = new_session(client)["id"]
    assert client.delete(f"/api/sessions/{sid}").status_code == 204
    assert client.get(f"/api/sessions/{sid}").status_code == 404
    assert client.delete(f"/api/sessions/{sid}").status_code == 404


def test_render_knobs_through_the_api(client):
    """samples_per_pixel, min_weight, specialize and tile_size are settings like the others."""
    sid = client.post("/api/sessions", json={"scenario": 2, "n": 16}).json()["id"]
    r = client.patch(
        f"/api/sessions/{sid}/settings",
        json={"samples_per_pixel": 4, "min_weight": 0.05, "specialize": False, "tile_size": 8},
    )
    assert r.status_code == 200, r.text
    body = r.json()
    assert (body["samples_per_pixel"], body["min_weight"], body["specialize"], body["tile_size"]) == (4, 0.05, False, 8)
    frame = client.get(
        f"/api/sessions/{sid}/frame", params={"width": 24, "height": 40, "format": "npy", "samples_per_pixel": 4}
    )
    assert frame.status_code == 200, frame.text
    for bad, field in [
        ({"samples_per_pixel": 3}, "samples_per_pixel"),
        ({"min_weight": 2}, "min_weight"),
        ({"tile_size": 1}, "tile_size"),
    ]:
        r = client.patch(f"/api/sessions/{sid}/settings", json=bad)
        assert r.status_code == 422 and field in r.text
    assert client.get(f"/api/sessions/{sid}").json()["settings"]["samples_per_pixel"] == 4


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


@pytest.mark.parametrize("kw,field", CREATE_CASES)
def test_create_rejects(client, kw, field):
    assert_422(client.post("/api/sessions", **kw), field)


@pytest.mark.parametrize("method,path,kw,field", SESSION_CASES)
def test_session_change_rejected_changes_nothing(client, sid, method, path, kw, field):
    before = snapshot(client, sid)
    r = client.request(method.upper(), f"/api/sessions/{sid}/{path}", **kw)
    assert_422(r, field)
    assert snapshot(client, sid) == before


def test_patch_and_create_refuse_a_mode_the_method_cannot_draw(client):
    """Was: accepted, and every later frame of the session failed."""
    sid = new_session(client)["id"]
    before = state_of(client, sid)
    assert_422_listing(client.patch(f"/api/sessions/{sid}/settings", json={"mode": "cones"}), "mode")
    assert state_of(client, sid) == before
    assert_422_listing(
        client.post("/api/sessions", json={"scenario": 3, "n": 16, "settings": {"mode": "cones"}}), "mode"
    )
    # The combination that can draw cones is accepted.
    r = client.patch(f"/api/sessions/{sid}/settings", json={"method": "hre", "mode": "cones"})
    assert r.status_code == 200 and r.json()["version"] == before["version"] + 1, r.text

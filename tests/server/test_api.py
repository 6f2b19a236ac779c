"""The API contract against the in-process app (httpx through Starlette's TestClient)."""

from __future__ import annotations

import io
import json
import time

import numpy as np
import pytest
from PIL import Image
from pocketray_server_support import SMALL, new_session

from renderer.scenarios import scenario
from renderer.settings import SETTINGS

SESSION_KEYS = {"id", "version", "settings", "scene_info", "camera"}
# A session's settings are exactly the declared ones (renderer.settings.SETTINGS).
SETTING_KEYS = {s.name for s in SETTINGS}


def timing(header: str) -> dict[str, float]:
    out = {}
    for entry in header.split(","):
        name, *params = entry.strip().split(";")
        for p in params:
            k, v = p.split("=")
            if k == "dur":
                out[name] = float(v)
    return out


def small_scene_json(n: int = 8) -> dict:
    return scenario(1, n, 0, 1.0).to_json()


def test_health_ready_info(ready_client):
    c = ready_client
    assert c.get("/api/health").json() == {"status": "ok"}
    r = c.get("/api/ready")
    assert r.status_code == 200
    body = r.json()
    assert body["ready"] is True and body["gl_renderer"] and body["gl_version"]
    info = c.get("/api/info").json()
    assert "bih" in info["methods"] and info["limits"]["max_work"] == 96 * 128 * 2
    # What the client's form needs to show only the settings that apply (issue #19).
    ms = info["method_settings"]
    assert set(ms) == set(info["methods"])
    # (integrator: the one-pass methods trace paths too; the ray engines do not)
    assert ms["bih"]["settings"] == ["max_prims", "max_tree_depth", "integrator"] and ms["bih"]["device"] is True
    assert ms["kdtree"]["settings"] == ["max_tree_depth", "integrator"]  # the SAH decides the leaves
    assert ms["bvh"]["settings"] == ["max_prims", "max_tree_depth", "update", "integrator"]
    assert ms["bruteforce"]["settings"] == ["integrator"] and ms["rayengine"]["settings"] == []
    assert ms["hre"]["settings"] == ["tile_size"] and ms["hre"]["device"] is False and "cones" in ms["hre"]["modes"]
    assert ms["auto"]["auto"] is True and ms["auto"]["settings"] == ms["bih"]["settings"]
    assert ms["bruteforce"]["tests_every_sphere"] and not ms["bih"]["tests_every_sphere"]
    assert info["samples_per_pixel"] == [1, 4, 9, 16] and info["render_timeout_s"] > 0
    assert info["museum_room_spheres"] == 576


def test_info_gives_the_legend_the_colors_of_the_modes(client):
    """The client's legend shows the colours of renderer.modes, which the shader is assembled with."""
    from renderer.modes import HEAT_SCALE, RECURSION_COLOR_NAMES, RECURSION_COLORS

    info = client.get("/api/info").json()
    assert [c["rgb"] for c in info["recursion_colors"]] == RECURSION_COLORS.tolist()
    assert [c["name"] for c in info["recursion_colors"]] == list(RECURSION_COLOR_NAMES)
    assert info["recursion_colors"][0] == {"rgb": [0.0, 0.0, 0.0], "name": "black"}  # level 0: a miss
    assert info["heat_scale"] == HEAT_SCALE


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


def test_gestures_json(client):
    sid = new_session(client)["id"]
    r = client.post(f"/api/sessions/{sid}/gesture", json={"type": "pan", "dx": 64, "dy": 0})
    assert r.status_code == 200
    body = r.json()
    assert body["version"] == 2
    # finger right → camera left; 64 px of a 64 px high view = 2·100·tan 30° world units
    assert body["camera"]["position"][0] == pytest.approx(-2 * 100 * np.tan(np.radians(30)))
    assert body["camera"]["target"][0] == pytest.approx(body["camera"]["position"][0])
    r = client.post(f"/api/sessions/{sid}/gesture", json={"type": "pinch", "scale": 4})
    assert r.json()["camera"]["position"][2] == pytest.approx(25.0) and r.json()["version"] == 3
    r = client.post(f"/api/sessions/{sid}/gesture", json={"type": "pan", "dx": 0, "dy": 100, "viewport_height": 200})
    assert r.json()["camera"]["position"][1] == pytest.approx(0.5 * 2 * 25 * np.tan(np.radians(30)))
    r = client.post(f"/api/sessions/{sid}/gesture", json={"type": "reset"})
    assert r.json() == {
        "version": 5,
        "camera": {"position": [0.0, 0.0, 100.0], "target": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov_y": 60.0},
    }


def test_orbit_gesture_turns_the_camera_about_its_target(client):
    sid = new_session(client)["id"]
    r = client.post(f"/api/sessions/{sid}/gesture", json={"type": "orbit", "yaw": 90, "pitch": 0})
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["version"] == 2
    assert body["camera"]["position"] == pytest.approx([100.0, 0.0, 0.0], abs=1e-9)  # to the camera's right
    assert body["camera"]["target"] == [0.0, 0.0, 0.0] and body["camera"]["up"] == [0.0, 1.0, 0.0]
    r = client.post(f"/api/sessions/{sid}/gesture", json={"type": "orbit", "pitch": 30})  # yaw defaults to 0
    p = r.json()["camera"]["position"]
    assert p == pytest.approx([100 * np.cos(np.radians(30)), -50.0, 0.0], abs=1e-9)  # down by 30°
    assert np.linalg.norm(p) == pytest.approx(100.0)
    r = client.post(f"/api/sessions/{sid}/gesture", json={"type": "orbit", "yaw": 0, "pitch": 300})
    pos = np.array(r.json()["camera"]["position"])
    polar = np.degrees(np.arccos(pos[1] / np.linalg.norm(pos)))
    assert polar == pytest.approx(179.0)  # clamped short of −up
    assert client.get(f"/api/sessions/{sid}").json()["version"] == 4


def test_frame_png_headers_and_image(ready_client):
    c = ready_client
    sid = new_session(c)["id"]
    r = c.get(f"/api/sessions/{sid}/frame", params={"width": 40, "height": 24})
    assert r.status_code == 200, r.text
    assert r.headers["content-type"] == "image/png"
    img = Image.open(io.BytesIO(r.content))
    assert img.size == (40, 24) and img.mode == "RGB"
    t = timing(r.headers["server-timing"])
    assert {"build", "upload", "trace", "encode", "total"} <= set(t)
    assert all(v >= 0 for v in t.values()) and t["total"] >= t["trace"]
    assert r.headers["x-session-version"] == "1" and r.headers["x-method"] == "bih"
    stats = json.loads(r.headers["x-stats"])
    assert stats["method"] == "bih" and stats["primitives"] == 64
    assert stats["leaves"] == stats["inner_nodes"] + 1 and stats["depth_max"] >= 1
    exposed = r.headers["access-control-expose-headers"]
    for h in ("Server-Timing", "X-Session-Version", "X-Method", "X-Stats"):
        assert h in exposed
    full = c.get(f"/api/sessions/{sid}/stats").json()
    assert full["inner_nodes"] == stats["inner_nodes"] and "leaf_histogram" in full


def test_frame_formats_jpeg_and_npy(ready_client):
    c = ready_client
    sid = new_session(c)["id"]
    r = c.get(f"/api/sessions/{sid}/frame", params={"format": "jpeg", "quality": 50, "width": 32, "height": 32})
    assert r.headers["content-type"] == "image/jpeg" and r.content[:2] == b"\xff\xd8"
    r = c.get(f"/api/sessions/{sid}/frame", params={"format": "npy", "width": 32, "height": 16})
    assert r.headers["content-type"] == "application/octet-stream"
    a = np.load(io.BytesIO(r.content))
    assert a.shape == (16, 32, 3) and a.dtype == np.uint8
    r = c.get(f"/api/sessions/{sid}/frame", params={"format": "npy", "mode": "depth", "width": 32, "height": 16})
    d = np.load(io.BytesIO(r.content))
    assert d.shape == (16, 32) and d.dtype == np.float32 and np.isfinite(d).any()
    r = c.get(f"/api/sessions/{sid}/frame", params={"format": "npy", "mode": "primid", "width": 32, "height": 16})
    p = np.load(io.BytesIO(r.content))
    assert p.dtype == np.int32 and p.min() >= -1 and p.max() <= 64


def test_gesture_with_frame_is_one_round_trip(ready_client):
    c = ready_client
    sid = new_session(c)["id"]
    r = c.post(
        f"/api/sessions/{sid}/gesture",
        params={"frame": 1, "width": 32, "height": 48, "format": "jpeg"},
        json={"type": "pinch", "scale": 2},
    )
    assert r.status_code == 200, r.text
    assert r.headers["content-type"] == "image/jpeg"
    assert r.headers["x-session-version"] == "2"
    assert "trace;dur=" in r.headers["server-timing"]
    assert c.get(f"/api/sessions/{sid}").json()["camera"]["position"] == [0.0, 0.0, 50.0]


def test_gesture_frame_shows_the_moved_camera(ready_client):
    """A frame after a pan equals a frame rendered with the moved camera set directly."""
    c = ready_client
    a = new_session(c)["id"]
    b = new_session(c)["id"]
    q = {"frame": 1, "format": "npy", "mode": "primid", "width": 32, "height": 48}
    moved = c.post(f"/api/sessions/{a}/gesture", params=q, json={"type": "pan", "dx": 5, "dy": -3})
    cam = c.get(f"/api/sessions/{a}").json()["camera"]
    c.put(f"/api/sessions/{b}/camera", json=cam)
    direct = c.get(f"/api/sessions/{b}/frame", params={k: v for k, v in q.items() if k != "frame"})
    assert np.array_equal(np.load(io.BytesIO(moved.content)), np.load(io.BytesIO(direct.content)))


def test_stateless_render(ready_client):
    c = ready_client
    body = {
        "scene": small_scene_json(8),
        "settings": {"width": 24, "height": 16, "format": "npy", "max_recursion_depth": 2, "mode": "primid"},
    }
    r = c.post("/api/render", json=body)
    assert r.status_code == 200, r.text
    a = np.load(io.BytesIO(r.content))
    assert a.shape == (16, 24) and a.dtype == np.int32
    assert "x-session-version" not in r.headers and r.headers["x-method"] == "bih"
    r = c.post("/api/render", json={"scene": small_scene_json(8), "settings": {"method": "bruteforce"}})
    assert r.status_code == 200 and r.headers["content-type"] == "image/png"
    assert r.headers["x-method"] == "bruteforce"


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


def test_static_client_shaders_and_docs(client):
    r = client.get("/shaders/raytrace.frag")
    assert r.status_code == 200 and "#version" in r.text
    assert client.put("/shaders/raytrace.frag", content=b"x").status_code == 405
    assert client.get("/docs").status_code == 200
    spec = client.get("/openapi.json").json()
    assert "/api/sessions/{session_id}/gesture" in spec["paths"]


def test_sessions_expire_after_the_idle_time(tmp_path):
    from fastapi.testclient import TestClient
    from pocketray_server_support import make_config

    from server.app import create_app

    with TestClient(create_app(make_config(tmp_path, session_ttl_s=1.0, warmup=False))) as c:
        idle = new_session(c)["id"]
        busy = new_session(c)["id"]
        for _ in range(6):
            time.sleep(0.25)
            assert c.get(f"/api/sessions/{busy}").status_code == 200  # use keeps it alive
        assert c.get(f"/api/sessions/{idle}").status_code == 404


def test_websocket_gesture_to_frame(ready_client):
    c = ready_client
    sid = new_session(c)["id"]
    with c.websocket_connect(f"/api/sessions/{sid}/ws") as ws:
        ws.send_text(json.dumps({"type": "pinch", "scale": 2, "frame": {"width": 32, "height": 48, "format": "jpeg"}}))
        meta = json.loads(ws.receive_text())
        assert meta["version"] == 2 and meta["camera"]["position"] == [0.0, 0.0, 50.0]
        assert meta["media_type"] == "image/jpeg" and "trace" in meta["timings"]
        assert ws.receive_bytes()[:2] == b"\xff\xd8"
        ws.send_text(json.dumps({"type": "pinch", "scale": -1}))
        err = json.loads(ws.receive_text())  # the HTTP route's 422 (server/api/errors.py)
        assert err["status"] == 422 and any("scale" in d["msg"] for d in err["detail"])
    assert c.get(f"/api/sessions/{sid}").json()["version"] == 2


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


def test_info_hands_out_the_measured_profiles(client):
    from renderer.profiles import INTERACTIVE, STILL
    from renderer.settings import RenderSettings

    info = client.get("/api/info").json()
    assert info["profiles"] == {"interactive": INTERACTIVE, "still": STILL}
    for name, profile in info["profiles"].items():  # each is a valid set of render settings
        RenderSettings(**{k: v for k, v in profile.items() if k != "resolution_scale"})


def test_new_sessions_default_to_the_still_profile(tmp_path):
    """Without default_render, a session's settings are RenderSettings' plus the measured 'still'
    profile, and the default work cap admits it at the client's largest 'fit' frame."""
    from renderer.profiles import STILL
    from server.config import ServerConfig

    config = ServerConfig(sqlite_path=tmp_path / "s.db")
    d = config.default_settings()
    for k in ("max_recursion_depth", "samples_per_pixel", "min_weight"):
        assert d[k] == STILL[k], k
    assert 1088 * 1088 * d["max_recursion_depth"] * d["samples_per_pixel"] <= config.max_work
    # default_render still overrides the profile.
    pinned = ServerConfig(sqlite_path=tmp_path / "t.db", default_render={"samples_per_pixel": 1})
    assert pinned.default_settings()["samples_per_pixel"] == 1

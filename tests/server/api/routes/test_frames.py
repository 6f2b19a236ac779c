"""The frame routes (server/api/routes/frames.py): gestures, session frames, stateless renders."""

from __future__ import annotations

import io
import json
import math

import numpy as np
import pytest
from PIL import Image
from pocketray_server_support import (
    GOOD_CAMERA,
    MUSEUM_FRAME,
    SMALL,
    assert_422,
    assert_422_listing,
    assert_422_msgs,
    create,
    ids,
    mesh_scene_json,
    museum_session,
    new_session,
    raw,
    scene_with,
    small_scene_json,
    snapshot,
    state_of,
    timing,
)

from renderer.scenes.animation import museum, pose


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


def test_method_limits_are_checked_before_a_gesture_is_applied(client, sid):
    """A method's own limits (here: mode 'cones' needs method 'hre') are a 422 up front."""
    from renderer.config.settings import METHOD_NAMES

    if "rayengine" not in METHOD_NAMES:
        return  # nothing to check with this renderer
    before = snapshot(client, sid)
    r = client.post(
        f"/api/sessions/{sid}/gesture?frame=1&method=rayengine&mode=cones", json={"type": "pinch", "scale": 2}
    )
    assert_422(r, "mode")
    assert snapshot(client, sid) == before


CONE_METHODS = ["bih", "bvh", "kdtree", "twolevel", "bruteforce", "auto"]


def distance(camera: dict) -> float:
    return math.dist(camera["position"], camera["target"])


@pytest.mark.parametrize("method", CONE_METHODS)
def test_a_refused_gesture_frame_moves_no_camera(client, method):
    """Rules out: 422 "mode 'cones' is not available with method 'bih'" after the pan was committed."""
    sid = new_session(client)["id"]
    before = state_of(client, sid)
    r = client.post(
        f"/api/sessions/{sid}/gesture",
        params={"frame": 1, "mode": "cones", "method": method},
        json={"type": "pan", "dx": 40, "dy": 0},
    )
    detail = assert_422_listing(r, "mode")
    assert detail[0]["loc"] == ["query", "mode"] and "hre" in detail[0]["msg"]
    assert state_of(client, sid) == before  # version 1, camera where it was


def test_a_timed_out_gesture_frame_retried_as_told_moves_the_camera_once(ready_client, monkeypatch):
    """Rules out: the 503 came after the gesture was committed, so the retry applied it twice."""
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


@pytest.mark.parametrize("method", ["bih", "bruteforce", "bvh", "kdtree", "twolevel", "auto"])
def test_frames_of_a_scene_with_meshes_are_served_by_the_methods_that_trace_triangles(api, method):
    sid = create(api, mesh_scene_json(), method=method, mode="primid").json()["id"]
    r = api.get(f"/api/sessions/{sid}/frame", params={"format": "npy"})
    assert r.status_code == 200, r.text
    ids = np.load(io.BytesIO(r.content))
    # sphere 0, plane 1, the icosphere's triangles 2 … 81, the box's 82 … 93 (FORMATS.md)
    assert ids.shape == (SMALL["height"], SMALL["width"])
    assert (ids >= 2).any() and (ids == 0).any(), np.unique(ids)
    assert ids.max() <= 1 + 80 + 12


def test_a_method_without_meshes_on_gpu_is_refused_with_422_meshes(api, monkeypatch):
    """The per-method refusal (Capabilities.meshes_on_gpu), for a method whose layout would
    hold spheres only — none does today, so bvh pretends: frames, renders and device data
    of a mesh scene are 422 'meshes' naming the methods that trace meshes."""
    import dataclasses

    from renderer.config.methods import METHODS

    monkeypatch.setattr(
        METHODS["bvh"], "capabilities", dataclasses.replace(METHODS["bvh"].capabilities, meshes_on_gpu=False)
    )
    sid = create(api, mesh_scene_json(), method="bvh").json()["id"]
    r = api.get(f"/api/sessions/{sid}/frame")
    assert_422_msgs(r, "meshes")
    assert "'bvh'" in r.text and "trace meshes are bih, bruteforce, kdtree, twolevel, auto" in r.text
    assert_422_msgs(api.get(f"/api/sessions/{sid}/device-data"), "meshes")
    assert_422_msgs(
        api.post("/api/render", json={"scene": mesh_scene_json(), "settings": {**SMALL, "method": "bvh"}}), "meshes"
    )


def server_timing(header: str) -> dict[str, float]:
    return {e.split(";")[0].strip(): float(e.split("dur=")[1]) for e in header.split(",")}


@pytest.mark.parametrize(
    "kind,method,scheme",
    [("rigid", "bvh", "refit"), ("incoherent", "bvh", "selective"), ("mixed", "twolevel", "refit")],
)
def test_session_frames_follow_the_animation_exactly(museum_ready_client, kind, method, scheme):
    """Each frame of a session, updated from the previous one, shows what brute force shows."""
    c = museum_ready_client
    s = museum_session(c, kind=kind, method=method, update=scheme)
    sid = s["id"]
    assert s["scene_info"]["animated"] and s["scene_info"]["n_moving"] == 48
    assert s["scene_info"]["n_spheres"] == 576 + 48
    previous = None
    for t in (0.0, 0.3, 0.6, 0.9):
        r = c.get(f"/api/sessions/{sid}/frame", params={**MUSEUM_FRAME, "time": t})
        got = ids(r)
        stats = r.headers["x-stats"]
        assert f'"time":{t}' in stats.replace(" ", "")
        bf = ids(c.get(f"/api/sessions/{sid}/frame", params={**MUSEUM_FRAME, "time": t, "method": "bruteforce"}))
        assert (got == bf).mean() >= 0.9999, f"{kind} t={t}"
        st = server_timing(r.headers["server-timing"])
        assert {"pose", "update", "trace"} <= set(st) and st["update"] >= 0
        if previous is not None:
            assert (got != previous).any(), "the scene moved between frames"
        previous = got


def test_a_frame_is_the_posed_scene(museum_ready_client):
    """A session frame at t equals a stateless brute-force render of ``pose(museum, t)``."""
    c = museum_ready_client
    sid = museum_session(c, n=32, kind="incoherent")["id"]
    t = 1.7
    frame = ids(c.get(f"/api/sessions/{sid}/frame", params={**MUSEUM_FRAME, "time": t}))
    posed = pose(museum(32, "incoherent", seed=2), t).scene
    assert posed.n_spheres < 576 + 32  # incoherent: some spheres are away at t
    body = {"scene": posed.to_json(), "settings": {**MUSEUM_FRAME, "method": "bruteforce"}}
    ref = ids(c.post("/api/render", json=body))
    assert (frame == ref).mean() >= 0.9999


@pytest.mark.parametrize(
    "params,field",
    [
        ({"time": -1}, "time"),
        ({"time": "nan"}, "time"),
        ({"update": "sometimes"}, "update"),
        ({"update_threshold": -0.5}, "update_threshold"),
    ],
)
def test_bad_frame_settings_are_422_naming_the_field(museum_ready_client, params, field):
    c = museum_ready_client
    sid = museum_session(c)["id"]
    r = c.get(f"/api/sessions/{sid}/frame", params=params)
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["query", field]
    v = c.get(f"/api/sessions/{sid}").json()["version"]
    r = c.patch(f"/api/sessions/{sid}/settings", json={"time": -1e9} if field == "time" else params)
    assert r.status_code == 422 and r.json()["detail"][0]["loc"][-1] == field
    assert c.get(f"/api/sessions/{sid}").json()["version"] == v  # nothing applied

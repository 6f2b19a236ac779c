"""``method=auto`` is resolved in one place (renderer.frame.plan) on one count, the tree's primitives: a scene
of meshes alone — no sphere, hundreds of triangles — gets the same method from the input caps, its
frames, its device data and its build statistics."""

from __future__ import annotations

from pocketray_server_support import SMALL

from renderer.config.methods import AUTO_CROSSOVER_N
from server.frames.device_data import decode_blob
from server.frames.pipeline import render_settings
from server.sessions.scenes import tree_primitives


def test_a_mesh_only_scenes_auto_method_is_the_same_in_caps_frames_device_data_and_stats(ready_client):
    c = ready_client
    body = {"mesh_scene": {"kind": "teapot", "detail": 0}, "settings": {**SMALL, "method": "auto"}}
    r = c.post("/api/sessions", json=body)
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    state = c.app.state.service.get(sid)
    n = tree_primitives(state.scene_info)
    assert state.scene_info["n_spheres"] == 0 and n >= AUTO_CROSSOVER_N
    by_caps = c.app.state.service.caps.check_work(render_settings(state.settings), n)
    frame = c.get(f"/api/sessions/{sid}/frame", params={"format": "png"})
    assert frame.status_code == 200, frame.text
    data = c.get(f"/api/sessions/{sid}/device-data")
    assert data.status_code == 200, data.text
    header, _ = decode_blob(data.content)
    stats = c.get(f"/api/sessions/{sid}/stats")
    assert stats.status_code == 200, stats.text
    methods = {
        "caps": by_caps,
        "frame": frame.headers["X-Method"],
        "device data": header["method"],
        "device shader": header["shader"]["method"],
        "stats": stats.json()["method"],
    }
    assert set(methods.values()) == {"bih"}, methods

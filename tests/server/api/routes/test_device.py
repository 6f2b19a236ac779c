"""The device-data route (server/api/routes/device.py): what a browser's GPU path is handed."""

from __future__ import annotations

import pytest
from pocketray_server_support import create, mesh_scene_json, museum_session

from renderer.animation import museum, pose
from server.frames.device_data import decode_blob

pytestmark = pytest.mark.gl  # every test here runs an app, whose lifespan starts the GL worker


def test_device_data_of_a_scene_with_meshes_holds_the_triangles(api):
    sid = create(api, mesh_scene_json()).json()["id"]
    r = api.get(f"/api/sessions/{sid}/device-data")
    assert r.status_code == 200, r.text
    from server.frames.device_data import decode_blob

    header, textures = decode_blob(r.content)
    assert "TRIANGLES" in header["shader"]["features"] and "u_triangles" in textures
    assert header["uniforms"]["u_tri_base"] == 2


def test_stats_and_device_data_pose_the_scene(museum_ready_client):
    c = museum_ready_client
    sid = museum_session(c, n=32, kind="incoherent", method="twolevel")["id"]
    st = c.get(f"/api/sessions/{sid}/stats", params={"time": 1.7}).json()
    assert st["method"] == "twolevel" and st["moving"] < 32 and st["static"] == 576
    r = c.get(f"/api/sessions/{sid}/device-data", params={"time": 1.7, "method": "bvh"})
    assert r.status_code == 200, r.text
    header, _ = decode_blob(r.content)
    assert header["settings"]["time"] == 1.7
    assert header["stats"]["primitives"] == pose(museum(32, "incoherent", seed=2), 1.7).scene.n_spheres

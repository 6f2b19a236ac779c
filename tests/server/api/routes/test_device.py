"""The device-data route (server/api/routes/device.py): what a browser's GPU path is handed."""

from __future__ import annotations

import pytest
from pocketray_server_support import create, mesh_scene_json, museum_session

from renderer.config.settings import RenderSettings
from renderer.frame.features import frame_features
from renderer.image import atrous
from renderer.limits import DEVICE_PATH_SAMPLES_PER_PASS
from renderer.scenes.animation import museum, pose
from renderer.scenes.scenarios import mesh_scene
from server.frames.device_data import decode_blob


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


def test_device_data_for_path_carries_the_servers_variant_and_light(api):
    """integrator=path (here the query's, over the session's whitted): the shader variant the server's
    frame compiles, a path's depth past Whitted's bound, the path
    integrator's uniforms and the display's tone map and exposure."""
    # (the body's settings over the Cornell box's recommended path + oidn)
    body = {"mesh_scene": {"kind": "cornell", "detail": 1}, "settings": {"integrator": "whitted", "denoise": "off"}}
    sid = api.post("/api/sessions", json=body).json()["id"]
    q = {"integrator": "path", "max_recursion_depth": 12, "samples_per_pixel": 5, "tone_map": "aces", "exposure": -1}
    r = api.get(f"/api/sessions/{sid}/device-data", params=q)
    assert r.status_code == 200, r.text
    header, _ = decode_blob(r.content)
    # the server's variant: the scene's features and the path integrator (GLRenderer.begin's choice)
    settings = RenderSettings(**{**q, "width": 8, "height": 8})
    features, depth = frame_features(mesh_scene("cornell", detail=1), settings)
    assert {"PATH", "EMISSION", "TRIANGLES"} <= set(header["shader"]["features"])
    assert header["shader"]["features"] == list(features.defines())
    assert header["shader"]["max_recursion_depth"] == depth == header["stats"]["recursion_depth"] == 12
    assert {k: header["settings"][k] for k in ("integrator", "tone_map", "exposure")} == {
        "integrator": "path",
        "tone_map": "aces",
        "exposure": -1.0,
    }
    assert header["settings"]["samples_per_pixel"] == 5
    assert header["path"] == {"samples_per_pass": DEVICE_PATH_SAMPLES_PER_PASS, "guides": False}
    assert "GUIDES" not in header["shader"]["features"] and header["settings"]["denoise"] == "off"
    u = header["uniforms"]
    assert u["u_num_emit_tris"] == 2 and u["u_emit_tri_area"] > 0 and u["u_light_scale"] > 0
    src = api.get(header["shader"]["url"])
    assert src.status_code == 200 and "u_sample_start" in src.text and "#define PATH 1\n" in src.text


@pytest.mark.parametrize("denoise", ["atrous", "oidn"])
def test_device_data_with_a_denoiser_writes_the_guides(api, denoise):
    """denoise on: the variant that writes the first hit's albedo and normal (the server's frame of
    the same settings compiles it too), which the device's à-trous filter reads."""
    sid = api.post("/api/sessions", json={"mesh_scene": {"kind": "cornell", "detail": 0}}).json()["id"]
    q = {"integrator": "path", "denoise": denoise}
    header, _ = decode_blob(api.get(f"/api/sessions/{sid}/device-data", params=q).content)
    features, _ = frame_features(mesh_scene("cornell", detail=0), RenderSettings(**q), guides=True)
    assert "GUIDES" in header["shader"]["features"] and header["shader"]["features"] == list(features.defines())
    assert header["path"]["guides"] is True and header["settings"]["denoise"] == denoise
    assert header["path"]["atrous"] == atrous.parameters()  # the filter's parameters, declared once
    src = api.get(header["shader"]["url"])
    assert src.status_code == 200 and "#define GUIDES 1\n" in src.text
    bad = api.get(f"/api/sessions/{sid}/device-data", params={**q, "denoise": "median"})
    assert bad.status_code == 422 and "denoise" in bad.text


def test_device_data_for_whitted_has_no_path(api):
    sid = create(api, mesh_scene_json()).json()["id"]
    header, _ = decode_blob(api.get(f"/api/sessions/{sid}/device-data").content)
    assert "PATH" not in header["shader"]["features"] and header["path"] is None
    assert header["settings"]["integrator"] == "whitted"


@pytest.mark.parametrize("method", ["rayengine", "hre"])
def test_the_ray_engines_refuse_path_on_the_device_and_the_server(api, method):
    sid = create(api, mesh_scene_json()).json()["id"]
    r = api.get(f"/api/sessions/{sid}/device-data", params={"integrator": "path", "method": method})
    assert r.status_code == 422, r.text
    r = api.patch(f"/api/sessions/{sid}/settings", json={"integrator": "path", "method": method})
    assert r.status_code == 422 and "integrator" in r.text, r.text


def test_device_data_takes_the_devices_layer_limit_and_reports_its_surface_bytes(api):
    """max_array_texture_layers (the device's MAX_ARRAY_TEXTURE_LAYERS) is a bounded query field; the
    header's surface says what a scene's textures and attribute records take on the device (nothing
    here: no texture, no texture array in the blob)."""
    sid = create(api, mesh_scene_json()).json()["id"]
    bad = api.get(f"/api/sessions/{sid}/device-data", params={"max_array_texture_layers": 0})
    assert bad.status_code == 422 and "max_array_texture_layers" in bad.text
    r = api.get(f"/api/sessions/{sid}/device-data", params={"max_array_texture_layers": 2048})
    assert r.status_code == 200, r.text
    header, textures = decode_blob(r.content)
    assert header["surface"] == {"texture_bytes": 0, "attribute_bytes": 0, "notices": []}
    assert "u_textures" not in textures and "TEXTURES" not in header["shader"]["features"]

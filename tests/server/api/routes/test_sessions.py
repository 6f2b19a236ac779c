"""The session routes (server/api/routes/sessions.py): create, read, change, delete; bad input is
422 naming the field, and a refusal changes nothing."""

from __future__ import annotations

import base64
import io
import json
import time
import zipfile

import numpy as np
import pytest
from pocketray_server_support import (
    GOOD_CAMERA,
    MAX_BODY,
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
)

from renderer.config.settings import SETTINGS
from renderer.geometry.meshes import box, icosphere
from renderer.geometry.scene import Scene
from renderer.gpu import texture_layout
from renderer.io.mesh_io import export_mesh
from renderer.materials.texture import Texture, decode_image
from renderer.scenes.scenarios import scenario
from tests.helpers import load_scaled, median_s
from tests.renderer.gltf_files import Gltf, png, triangle

SESSION_KEYS = {"id", "version", "settings", "scene_info", "camera"}


# A session's settings are exactly the declared ones (renderer.config.settings.SETTINGS).
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
        "sky": False,
        "animated": False,
        "n_moving": 0,
        "museum": None,
        "mesh_scene": None,
        "n_meshes": 0,
        "n_triangles": 0,
        "n_unique_triangles": 0,
        "n_textures": 0,
        "texture_bytes": 0,
        "attribute_bytes": 0,
        "n_degenerate_triangles": 0,
        "n_moving_meshes": 0,
        "n_shapes": 0,
        "n_moving_shapes": 0,
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
    ({"json": {"seed": 1}}, "scenario"),  # (an empty body is the default demo scene)
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
    """Rules out: accepted, and every later frame of the session failed."""
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


def upload(api, sid: str, data: bytes, **query):
    return api.post(
        f"/api/sessions/{sid}/meshes", params=query, content=data, headers={"content-type": "application/octet-stream"}
    )


def vm_hwm_kib() -> int:
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
    raise AssertionError("no VmHWM")


def test_a_scene_with_meshes_is_stored_and_streamed_back_in_world_space(api):
    body = mesh_scene_json()
    r = create(api, body)
    assert r.status_code == 201, r.text
    info = r.json()["scene_info"]
    assert (info["n_spheres"], info["n_planes"], info["n_meshes"], info["n_triangles"]) == (1, 1, 2, 80 + 12)
    assert info["n_degenerate_triangles"] == 0
    sid = r.json()["id"]
    got = api.get(f"/api/sessions/{sid}/scene").json()
    expect = Scene.from_json(body).to_json()
    assert got["meshes"] == expect["meshes"]
    assert got["meshes"][1]["vertices"][0] == [8.0, -2.0, -2.0]  # the transform applied once
    assert "transform" not in got["meshes"][1]
    # what comes back goes in again as the same scene
    again = create(api, {k: v for k, v in got.items() if k != "camera"} | {"camera": got["camera"]})
    assert again.status_code == 201
    again_scene = api.get(f"/api/sessions/{again.json()['id']}/scene").json()
    assert again_scene["meshes"] == got["meshes"]
    # statistics of a build over spheres and triangles
    stats = api.get(f"/api/sessions/{sid}/stats").json()
    assert stats["triangles"] == 92 and stats["primitives"] == 93


def test_the_ray_engines_refuse_a_scene_with_meshes_naming_the_method(api):
    r = create(api, mesh_scene_json(), method="rayengine")
    assert_422_msgs(r, "method")
    assert "spheres and planes only" in r.text
    sid = create(api, mesh_scene_json()).json()["id"]
    assert_422_msgs(api.patch(f"/api/sessions/{sid}/settings", json={"method": "hre"}), "method")


@pytest.mark.parametrize(
    "change,field",
    [
        ({"vertices": [[0, 0, 0], [1, 0, 0]], "triangles": [[0, 1, 2]]}, "scene.meshes[1].triangles[0]"),
        ({"triangles": [[0, 1, 2], [0, 1]]}, "scene.meshes[1].triangles[1]"),
        ({"triangles": [[0, 1, -3]]}, "scene.meshes[1].triangles[0]"),
        ({"vertices": [[0, 0, 0], [1, 0], [0, 1, 0]], "triangles": [[0, 1, 2]]}, "scene.meshes[1].vertices[1]"),
        ({"normals": [[0, 0, 1]] * 3}, "scene.meshes[1].normals"),
        ({"normals": [[0, 0, 0]] * 8}, "scene.meshes[1].normals[0]"),
        ({"material": 5}, "scene.meshes[1].material"),
        ({"transform": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]]}, "scene.meshes[1].transform"),
        ({"transform": [[2e7, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}, "scene.meshes[1].vertices[0]"),
        ({"uv": []}, "scene.meshes[1].uv"),
    ],
)
def test_bad_meshes_are_refused_naming_the_field(api, change, field):
    assert_422_msgs(create(api, mesh_scene_json(**change)), field)


def test_a_nan_vertex_is_refused_naming_it(api):
    text = json.dumps({"scene": mesh_scene_json(), "settings": SMALL})
    bad = text.replace("[-1.0, -1.0, -1.0]", "[-1.0, NaN, -1.0]", 1)
    assert bad != text
    assert_422_msgs(api.post("/api/sessions", **raw(bad)), "scene.meshes[1].vertices[0][1]")


def test_too_many_triangles_422_over_the_cap_and_413_over_the_body_limit(api):
    many = icosphere(4)  # 5,120 triangles > POCKETRAY_MAX_TRIANGLES = 3,000 of this app
    body = mesh_scene_json()
    body["meshes"] = [{"vertices": np.round(many.vertices, 3).tolist(), "triangles": many.triangles.tolist()}]
    assert len(json.dumps(body)) < MAX_BODY
    r = create(api, body)
    assert_422_msgs(r, "scene.meshes")
    assert "POCKETRAY_MAX_TRIANGLES" in r.text
    huge = icosphere(5)
    body["meshes"] = [{"vertices": huge.vertices.tolist(), "triangles": huge.triangles.tolist()}]
    assert create(api, body).status_code == 413


@pytest.mark.parametrize("fmt", ["obj", "ply", "stl", "glb"])
def test_a_model_file_is_added_to_the_session_scene(api, fmt):
    sid = create(api, mesh_scene_json()).json()["id"]
    version = api.get(f"/api/sessions/{sid}").json()["version"]
    camera = api.get(f"/api/sessions/{sid}").json()["camera"]
    r = upload(api, sid, export_mesh(icosphere(2, radius=1.5), fmt), format=fmt, material=1, size=10)
    assert r.status_code == 201, r.text
    out = r.json()
    assert out["version"] == version + 1 and out["mesh"] == 2
    assert out["scene_info"]["n_triangles"] == 92 + 320 and out["first_id"] == 2 + 92
    scene = api.get(f"/api/sessions/{sid}/scene").json()
    added = np.array(scene["meshes"][2]["vertices"])
    assert (added.max(0) - added.min(0)).max() == pytest.approx(10.0) and added[:, 1].min() == pytest.approx(-20.0)
    assert scene["meshes"][2]["material"] == 1 and ("normals" in scene["meshes"][2]) == (fmt != "stl")
    # the camera is framed again to show the model: the answer says so
    assert api.get(f"/api/sessions/{sid}").json()["camera"] == out["camera"] != camera


def test_bad_uploads_are_refused_and_change_nothing(api):
    sid = create(api, mesh_scene_json()).json()["id"]
    before = api.get(f"/api/sessions/{sid}").json()
    assert_422_msgs(upload(api, sid, b"this is not a mesh", format="ply"), "body")
    assert_422_msgs(upload(api, sid, b"", format="obj"), "body")
    assert_422_msgs(upload(api, sid, export_mesh(box(), "obj"), format="dae"), "format")
    assert_422_msgs(upload(api, sid, export_mesh(box(), "obj"), format="obj", material=9), "material")
    over = upload(api, sid, export_mesh(icosphere(4), "stl"), format="stl")  # 5,120 triangles
    assert_422_msgs(over, "body")
    assert "POCKETRAY_MAX_TRIANGLES" in over.text
    assert upload(api, sid, b"\0" * (MAX_BODY + 1), format="stl").status_code == 413
    assert api.get(f"/api/sessions/{sid}").json() == before
    assert upload(api, "nosuchsession", export_mesh(box(), "obj"), format="obj").status_code == 404


def textured_glb(image: bytes) -> bytes:
    """One triangle mesh on two nodes, its material's base colour the PNG ``image`` (in the GLB)."""
    g = Gltf()
    uv = g.accessor([[0, 0], [1, 0], [0, 1]])
    g.add("images", {"bufferView": g.view(image), "mimeType": "image/png"})
    g.add("textures", {"source": 0})
    material = g.add("materials", {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0}})
    mesh = g.mesh(triangle(g, TEXCOORD_0=uv) | {"material": material})
    g.add("nodes", {"mesh": mesh, "translation": [0, 0, 0]})
    g.add("nodes", {"mesh": mesh, "translation": [2, 0, 0]})
    g.scene(0, 1)
    return g.glb()


def test_a_textured_glb_arrives_with_its_material_and_texture_or_not_at_all(api):
    sid = create(api, mesh_scene_json()).json()["id"]
    before = api.get(f"/api/sessions/{sid}").json()
    pixels = np.array([[[255, 0, 0, 255], [0, 0, 255, 255]]], np.uint8)
    # refused, each naming its problem, and nothing stored: a broken image, an extension not read
    bad = upload(api, sid, textured_glb(b"\x89PNG\r\n\x1a\n broken"), format="glb")
    assert_422_msgs(bad, "body")
    assert "images[0]" in bad.text
    g = Gltf()
    g.add("nodes", {"mesh": g.mesh(triangle(g))})
    g.scene(0)
    g.doc["extensionsRequired"] = ["KHR_materials_clearcoat"]
    assert "KHR_materials_clearcoat" in upload(api, sid, g.glb(), format="glb").text
    assert api.get(f"/api/sessions/{sid}").json() == before

    r = upload(api, sid, textured_glb(png(pixels)), format="glb", size=10)
    assert r.status_code == 201, r.text
    out = r.json()
    info = out["scene_info"]
    assert out["n_meshes"] == 2 and out["n_textures"] == 1 and out["mesh"] == 2
    assert info["n_triangles"] == 92 + 2 and info["n_unique_triangles"] == 92 + 1  # one mesh, two nodes
    assert info["n_textures"] == 1 and info["texture_bytes"] == texture_layout.array_bytes(
        (Texture(np.zeros((1, 2, 4), np.uint8)),)
    )
    scene = api.get(f"/api/sessions/{sid}/scene").json()
    material = scene["materials"][-1]
    assert material["kind"] == "pbr" and material["base_color_texture"] == 0 and material["metallic"] == 0
    assert all(m["material"] == len(scene["materials"]) - 1 and "uvs" in m for m in scene["meshes"][2:])
    (texture,) = scene["textures"]
    assert texture["srgb"] is True
    np.testing.assert_array_equal(decode_image(texture["png"], "png"), pixels)


def zipped(files: dict[str, bytes]) -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in files.items():
            z.writestr(name, data)
    return out.getvalue()


def test_a_zipped_gltf_folder_arrives_with_its_image_and_without_a_missing_one_said(api):
    from tests.renderer.gltf_files import Gltf, png, triangle

    g = Gltf()
    uv = g.accessor([[0, 0], [1, 0], [0, 1]])
    g.add("images", {"uri": "maps/skin.png"})
    g.add("textures", {"source": 0})
    g.add(
        "nodes",
        {
            "mesh": g.mesh(
                triangle(g, TEXCOORD_0=uv)
                | {"material": g.add("materials", {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}})}
            )
        },
    )
    g.scene(0)
    folder = {"box/box.gltf": g.gltf("box.bin"), "box/box.bin": bytes(g.binary)}
    sid = create(api, mesh_scene_json()).json()["id"]
    missing = upload(api, sid, zipped(folder), format="zip")  # the model without its texture, said
    assert missing.status_code == 201, missing.text
    assert missing.json()["scene_info"]["n_textures"] == 0
    assert "'maps/skin.png', which is not beside the model" in missing.json()["notice"]
    sid = create(api, mesh_scene_json()).json()["id"]
    image = png(np.full((3, 3, 4), 90, np.uint8))
    r = upload(api, sid, zipped({**folder, "box/maps/skin.png": image}), format="zip")
    assert r.status_code == 201, r.text
    assert r.json()["scene_info"]["n_textures"] == 1
    (texture,) = api.get(f"/api/sessions/{sid}/scene").json()["textures"]
    assert texture["name"] == "maps/skin.png"


def test_a_zipped_model_folder_is_added_and_a_hostile_zip_changes_nothing(api):
    """format=zip: the model file and its side files in one body, opened in the model worker; each
    hostile archive a 422 naming its problem, the session as it was."""
    sid = create(api, mesh_scene_json()).json()["id"]
    version = api.get(f"/api/sessions/{sid}").json()["version"]
    obj = b"mtllib ball.mtl\n" + export_mesh(icosphere(2), "obj")
    r = upload(
        api, sid, zipped({"ball/ball.obj": obj, "ball/ball.mtl": b"newmtl a\nKd 1 0 0\n"}), format="zip", size=10
    )
    assert r.status_code == 201, r.text
    assert r.json()["version"] == version + 1 and r.json()["scene_info"]["n_triangles"] == 92 + 320
    before = api.get(f"/api/sessions/{sid}").json()
    scene_before = api.get(f"/api/sessions/{sid}/scene").json()
    box_obj = export_mesh(box(), "obj")
    for body, named in [
        (zipped({"bomb.obj": b"\0" * (4 << 20)}), "MAX_ARCHIVE_RATIO"),
        (zipped({"../box.obj": box_obj}), "'../box.obj'"),
        (zipped({"/box.obj": box_obj}), "absolute name"),
        (zipped({"box.obj": box_obj, "inner.zip": zipped({"box.obj": box_obj})}), "archive inside the archive"),
        (
            zipped({"box.obj": box_obj, "skin.png": b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR" + bytes([0, 1, 0, 0] * 2)}),
            "MAX_MODEL_IMAGE",
        ),
        (b"PK\x05\x06" + b"\0" * 6 + b"\xff\x7f" + b"\0" * 10, "MAX_ARCHIVE_ENTRIES"),
        (box_obj, "not a zip"),
    ]:
        assert_422_msgs(upload(api, sid, body, format="zip"), named)
    assert api.get(f"/api/sessions/{sid}").json() == before
    assert api.get(f"/api/sessions/{sid}/scene").json() == scene_before


def test_a_gltf_sent_alone_is_told_to_come_as_a_zip(api):
    gltf = json.dumps(
        {"asset": {"version": "2.0"}, "buffers": [{"uri": "box.bin", "byteLength": 36}], "meshes": []}
    ).encode()
    r = api.post(
        "/api/meshes", params={"format": "gltf"}, content=gltf, headers={"content-type": "application/octet-stream"}
    )
    assert_422_msgs(r, "format=zip")
    old = json.dumps({"asset": {"version": "1.0"}, "buffers": {"b": {"uri": "b.bin"}}}).encode()
    r = api.post(
        "/api/meshes", params={"format": "gltf"}, content=old, headers={"content-type": "application/octet-stream"}
    )
    assert_422_msgs(r, "glTF 1.0 is not supported; convert to glTF 2.0")


def test_a_model_file_converts_to_mesh_json_that_a_scene_takes(api):
    r = api.post(
        "/api/meshes",
        params={"format": "stl"},
        content=export_mesh(icosphere(1), "stl"),
        headers={"content-type": "application/octet-stream"},
    )
    assert r.status_code == 200, r.text
    mesh = r.json()
    assert len(mesh["triangles"]) == 80 and "normals" not in mesh
    body = mesh_scene_json()
    body["meshes"] = [mesh]
    assert create(api, body).status_code == 201
    assert_422_msgs(
        api.post(
            "/api/meshes",
            params={"format": "glb"},
            content=b"nope",
            headers={"content-type": "application/octet-stream"},
        ),
        "body",
    )


def test_a_motion_can_move_a_mesh_through_the_api(api):
    body = mesh_scene_json()
    body["motions"] = [
        {"kind": "rigid", "mesh": 1, "angular_velocity": 0.5},
        {"kind": "deformable", "first": 0, "count": 1},
    ]
    r = create(api, body)
    assert r.status_code == 201, r.text
    info = r.json()["scene_info"]
    assert info["animated"] and info["n_moving_meshes"] == 1 and info["n_moving"] == 1
    got = api.get(f"/api/sessions/{r.json()['id']}/scene").json()
    assert got["motions"][0]["mesh"] == 1 and "first" not in got["motions"][0]
    body["motions"] = [{"kind": "rigid", "mesh": 1, "first": 0, "count": 1}]
    assert_422_msgs(create(api, body), "motions")
    body["motions"] = [{"kind": "incoherent", "mesh": 0}]
    assert_422_msgs(create(api, body), "scene.motions[0].mesh")


def test_a_mesh_scene_recipe_makes_a_session_of_its_triangles(api):
    from renderer.scenes.scenarios import mesh_scene

    r = api.post("/api/sessions", json={"mesh_scene": {"kind": "mixed", "detail": 1}, "settings": SMALL})
    assert r.status_code == 201, r.text
    info = r.json()["scene_info"]
    want = mesh_scene("mixed", 1)
    assert info["mesh_scene"] == {"kind": "mixed", "detail": 1, "smooth": True, "sky": False}
    assert info["n_triangles"] == want.n_triangles and info["n_meshes"] == 2 and info["n_spheres"] == 27
    sid = r.json()["id"]
    frame = api.get(f"/api/sessions/{sid}/frame", params={"mode": "primid", "format": "npy"})
    ids = np.load(io.BytesIO(frame.content))
    assert (ids >= want.triangle_id_base).any()  # its triangles are in the frame
    # A model added to it: a scene of its own (no recipe any more), the triangles counted.
    model = export_mesh(box((0, 0, 0), (1, 1, 1)), "obj")
    added = api.post(f"/api/sessions/{sid}/meshes", params={"format": "obj", "size": 5}, content=model)
    assert added.status_code == 201 and added.json()["scene_info"].get("mesh_scene") is None
    assert added.json()["scene_info"]["n_triangles"] == want.n_triangles + 12
    # Refused naming the field: an unknown kind, a detail out of range or over the triangle cap, two recipes.
    for body, field in [
        ({"mesh_scene": {"kind": "dragon"}}, "kind"),
        ({"mesh_scene": {"detail": 9}}, "detail"),
        ({"mesh_scene": {"kind": "room", "detail": 3}}, "mesh_scene"),
        ({"mesh_scene": {}, "scenario": 1, "n": 4}, "mesh_scene"),
    ]:
        bad = api.post("/api/sessions", json=body)
        assert bad.status_code == 422, (body, bad.text)
        assert any(field in [str(x) for x in d["loc"]] or field in d["msg"] for d in bad.json()["detail"]), bad.text


def test_hostile_model_files_get_a_quick_422_naming_the_problem(api):
    """A 250-byte glTF whose accessor claims 30,000,000 vertices (before: 2.3 GB of peak memory
    and 7.5 s, in the service's own process, then 422), a node tree deeper than the limit, a
    binary STL whose header count disagrees with its length (before: ModuleNotFoundError where
    charset-normalizer was not installed), a PLY short of its declared faces and an OBJ face
    of index 0 (both accepted before): each refused with 422 saying what is wrong."""
    octets = {"content-type": "application/octet-stream"}

    def small() -> None:
        r = api.post("/api/meshes", params={"format": "obj"}, content=export_mesh(box(), "obj"), headers=octets)
        assert r.status_code == 200

    small()  # the parser processes have started
    small_s = median_s(small, 3)  # a small file's parse, as loaded as the machine is now
    claim = json.dumps(
        {
            "asset": {"version": "2.0"},
            "bufferViews": [],
            "accessors": [{"componentType": 5126, "count": 30_000_000, "type": "VEC3"}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "nodes": [{"mesh": 0}],
            "scenes": [{"nodes": [0]}],
            "scene": 0,
        }
    ).encode()
    sid = create(api, mesh_scene_json()).json()["id"]
    hwm = vm_hwm_kib()
    for send in (
        lambda: api.post("/api/meshes", params={"format": "gltf"}, content=claim, headers=octets),
        lambda: upload(api, sid, claim, format="gltf"),
    ):
        t0 = time.perf_counter()
        r = send()
        assert time.perf_counter() - t0 < load_scaled(3.0, small_s, 30), small_s
        assert_422_msgs(r, "body")
        assert "accessors[0].count = 30,000,000; at most 3,145,728 allowed" in r.text
    assert vm_hwm_kib() - hwm < 100 * 1024  # KiB: no array of 30 M vertices here

    stl = export_mesh(icosphere(1), "stl")
    r = upload(api, sid, stl[:80] + (81).to_bytes(4, "little") + stl[84:], format="stl")
    assert_422_msgs(r, "body")
    assert "header says 81 triangles, which take 84 + 50 × 81 = 4,134 bytes; the file has 4,084" in r.text
    ply = (
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        b"element face 1000\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    )
    assert "element face 1,000 (1,003 rows); the file holds 4" in upload(api, sid, ply, format="ply").text
    r = upload(api, sid, b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", format="obj")
    assert_422_msgs(r, "body")
    assert "vertex index 0" in r.text
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes()
    nodes = [{"children": [i + 1]} for i in range(299)] + [{"mesh": 0}]
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": 36}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": nodes,
        "scenes": [{"nodes": [0]}],
        "scene": 0,
    }
    doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(tri).decode()
    r = upload(api, sid, json.dumps(doc).encode(), format="gltf")
    assert_422_msgs(r, "body")
    assert "MAX_MODEL_NODE_DEPTH" in r.text
    assert api.get(f"/api/sessions/{sid}").json()["scene_info"]["n_meshes"] == 2  # nothing was added


def test_uploaded_scene_with_motions_round_trips(museum_ready_client):
    c = museum_ready_client
    d = scenario(1, 27, 0, 1.0).to_json()
    d["motions"] = [
        {"kind": "rigid", "first": 0, "count": 9, "angular_velocity": 1.0},
        {"kind": "deformable", "first": 9, "count": 9, "amplitude": 0.5},
    ]
    r = c.post("/api/sessions", json={"scene": d, "settings": SMALL})
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    assert r.json()["scene_info"]["n_moving"] == 18
    back = c.get(f"/api/sessions/{sid}/scene").json()
    assert [m["kind"] for m in back["motions"]] == ["rigid", "deformable"]
    assert back["motions"][0]["angular_velocity"] == 1.0 and len(back["spheres"]) == 27
    a = ids(c.get(f"/api/sessions/{sid}/frame", params={**MUSEUM_FRAME, "time": 0.0}))
    b = ids(c.get(f"/api/sessions/{sid}/frame", params={**MUSEUM_FRAME, "time": 1.0}))
    assert (a != b).any()


@pytest.mark.parametrize(
    "motion,loc",
    [
        ({"kind": "rigid", "first": 0, "count": 4, "axis": [0, 0, 0]}, ["body", "scene", "motions", 0, "axis"]),
        (
            {"kind": "rigid", "first": 0, "count": 4, "pivot": [9e6, 0, 0], "amplitude": [5e6, 0, 0]},
            ["body", "scene", "motions", 0],
        ),
        ({"kind": "deformable", "first": 4, "count": 40}, ["body", "scene", "motions", 0, "count"]),
        (
            {"kind": "incoherent", "first": 0, "count": 4, "box_min": [0, 0, 0], "box_max": [1, -1, 1]},
            ["body", "scene", "motions", 0, "box_max", 1],
        ),
        ({"kind": "wobble", "first": 0, "count": 4}, ["body", "scene", "motions", 0]),
    ],
)
def test_bad_motions_are_422_naming_the_field(museum_client, motion, loc):
    d = scenario(1, 8, 0, 1.0).to_json()
    d["motions"] = [motion]
    r = museum_client.post("/api/sessions", json={"scene": d, "settings": SMALL})
    assert r.status_code == 422, r.text
    got = r.json()["detail"][0]["loc"]
    assert got[: len(loc)] == loc, got
    # PUT scene: the same error one level up, and the session keeps its scene.
    sid = museum_session(museum_client, n=8)["id"]
    before = museum_client.get(f"/api/sessions/{sid}").json()
    r = museum_client.put(f"/api/sessions/{sid}/scene", json=d)
    assert r.status_code == 422 and r.json()["detail"][0]["loc"][: len(loc) - 1] == ["body", *loc[2:]]
    assert museum_client.get(f"/api/sessions/{sid}").json() == before


def test_one_scene_source_per_session(museum_client):
    r = museum_client.post("/api/sessions", json={"museum": {"n": 8}, "scenario": 1, "n": 8})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "scenario"]
    r = museum_client.post("/api/sessions", json={"museum": {"n": 8, "kind": "sideways"}})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"][:3] == ["body", "museum", "kind"]


def test_sessions_stored_before_animation_still_work(museum_ready_client):
    """A session whose stored settings predate time/update (an older process wrote it) renders,
    builds statistics and packs device data with the defaults."""
    import dataclasses

    c = museum_ready_client
    sid = c.post("/api/sessions", json={"scenario": 1, "n": 8, "settings": SMALL}).json()["id"]
    new_keys = ("time", "update", "update_threshold")
    c.app.state.service.store.update(
        sid, lambda old: dataclasses.replace(old, settings={k: v for k, v in old.settings.items() if k not in new_keys})
    )
    s = c.get(f"/api/sessions/{sid}").json()["settings"]
    assert (s["time"], s["update"]) == (0.0, "rebuild")
    assert c.get(f"/api/sessions/{sid}/stats").status_code == 200
    assert c.get(f"/api/sessions/{sid}/device-data").status_code == 200
    assert c.get(f"/api/sessions/{sid}/frame", params={"format": "npy"}).status_code == 200


# ---- demo scenes: defaults, framing for the client's aspect, models that land in view ------------
PORTRAIT = 390 / 844


def object_boxes_of(scene_json: dict) -> list[np.ndarray]:
    """Each sphere's and mesh's box, read from scene JSON (what GET …/scene answers)."""
    boxes = [
        np.array([np.subtract(s["center"], s["radius"]), np.add(s["center"], s["radius"])])
        for s in scene_json["spheres"]
    ]
    for m in scene_json.get("meshes", []):
        v = np.array(m["vertices"], dtype=float)
        boxes.append(np.array([v.min(axis=0), v.max(axis=0)]))
    return boxes


def boxes_overlap(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(np.all(a[0] < b[1]) and np.all(b[0] < a[1]))


def test_an_empty_body_makes_the_default_demo_scene(client):
    from renderer.scenes.scenarios import DEFAULT_DEMO

    r = client.post("/api/sessions", json={"settings": SMALL})
    assert r.status_code == 201, r.text
    info = r.json()["scene_info"]
    assert {"mesh_scene": info["mesh_scene"]["kind"]} == {"mesh_scene": DEFAULT_DEMO.recipe["mesh_scene"]["kind"]}
    assert info["n_spheres"] == 512 and r.json()["settings"]["width"] == SMALL["width"]
    scene = client.get(f"/api/sessions/{r.json()['id']}/scene").json()
    assert scene["environment"]["image"] == "sky"


def test_a_demo_scene_opens_with_its_recommended_settings_and_the_body_wins(client):
    r = client.post("/api/sessions", json={"mesh_scene": {"kind": "cornell", "detail": 0}, "settings": SMALL})
    assert r.status_code == 201, r.text
    assert r.json()["settings"]["integrator"] == "path" and r.json()["settings"]["denoise"] == "oidn"
    mine = {**SMALL, "integrator": "whitted"}
    r = client.post("/api/sessions", json={"mesh_scene": {"kind": "cornell", "detail": 0}, "settings": mine})
    assert r.status_code == 201 and r.json()["settings"]["integrator"] == "whitted", r.text
    assert r.json()["settings"]["denoise"] == "oidn"  # the ones the body does not name still apply
    # a scene with no recommendation keeps the service's defaults
    plain = new_session(client)
    assert plain["settings"]["integrator"] == "whitted" and plain["settings"]["denoise"] == "off"


def test_a_session_made_for_an_aspect_is_framed_for_it_and_a_reset_frames_again(client):
    from renderer.scenes.scenarios import framed, mesh_scene

    body = {"mesh_scene": {"kind": "table"}, "settings": SMALL, "aspect": PORTRAIT}
    r = client.post("/api/sessions", json=body)
    assert r.status_code == 201, r.text
    want = framed(mesh_scene("table"), PORTRAIT).camera.to_json()
    assert r.json()["camera"] == want
    assert r.json()["camera"] != mesh_scene("table").camera.to_json()  # the recipe's own is for landscape
    sid = r.json()["id"]
    client.post(f"/api/sessions/{sid}/gesture", json={"type": "orbit", "yaw": 40})
    back = client.post(f"/api/sessions/{sid}/gesture", json={"type": "reset"})
    assert back.status_code == 200, back.text
    assert client.get(f"/api/sessions/{sid}").json()["camera"] == want
    wide = client.post(f"/api/sessions/{sid}/gesture", json={"type": "reset", "aspect": 16 / 9})
    assert wide.status_code == 200, wide.text
    assert client.get(f"/api/sessions/{sid}").json()["camera"] == framed(mesh_scene("table"), 16 / 9).camera.to_json()
    # without an aspect a recipe keeps its own camera (the benchmarks' and the thesis's)
    assert new_session(client)["camera"] == scenario(3, 64, 1).camera.to_json()
    # a full scene's camera is its author's, on reset too
    full = client.post("/api/sessions", json={"scene": small_scene_json(), "settings": SMALL, "aspect": PORTRAIT})
    assert full.status_code == 201 and full.json()["camera"] == small_scene_json()["camera"], full.text
    fid = full.json()["id"]
    client.post(f"/api/sessions/{fid}/gesture", json={"type": "reset"})
    assert client.get(f"/api/sessions/{fid}").json()["camera"] == small_scene_json()["camera"]


@pytest.mark.parametrize("aspect", [0.1, 6.0, "wide"])
def test_an_aspect_out_of_range_is_refused_naming_the_range(client, aspect):
    r = client.post("/api/sessions", json={"mesh_scene": {"kind": "table"}, "settings": SMALL, "aspect": aspect})
    assert r.status_code == 422, r.text
    assert any("aspect" in [str(x) for x in d["loc"]] for d in r.json()["detail"]), r.text
    if not isinstance(aspect, str):
        assert any("0.2" in d["msg"] or "5" in d["msg"] for d in r.json()["detail"]), r.text


def test_uploaded_models_stand_on_free_floor_in_their_own_material_and_in_view(api):
    r = api.post(
        "/api/sessions", json={"mesh_scene": {"kind": "teapot", "detail": 0}, "settings": SMALL, "aspect": PORTRAIT}
    )
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    before = api.get(f"/api/sessions/{sid}/scene").json()
    model = export_mesh(box((0, 0, 0), (2, 3, 1)), "obj")
    answers = [upload(api, sid, model, format="obj", size=12) for _ in range(2)]
    for a in answers:
        assert a.status_code == 201, a.text
        assert a.json()["notice"].startswith("placed at x ") and "beside the scene" in a.json()["notice"]
    scene = api.get(f"/api/sessions/{sid}/scene").json()
    boxes = object_boxes_of(scene)
    assert len(boxes) == len(object_boxes_of(before)) + 2
    for new in (-2, -1):  # each model's box overlaps no other object's box, the other model's included
        others = [b for i, b in enumerate(boxes) if i != len(boxes) + new]
        assert not any(boxes_overlap(boxes[new], b) for b in others), (boxes[new], others)
        assert boxes[new][0][1] == pytest.approx(-20.0)  # standing on the floor
        placed = answers[new].json()["placed"]
        assert placed[0] == pytest.approx((boxes[new][0][0] + boxes[new][1][0]) / 2, abs=0.06)
    # a material of their own, neutral, not one of the scene's
    materials = scene["materials"]
    assert len(materials) == len(before["materials"]) + 1
    assert [m["material"] for m in scene["meshes"][-2:]] == [len(materials) - 1] * 2
    clay = np.array(materials[-1]["color"])
    assert clay.max() - clay.min() < 0.1 and materials[-1] not in before["materials"]
    # the camera shows the models and the teapot (every object box inside the portrait frame)
    cam = answers[-1].json()["camera"]
    assert cam == api.get(f"/api/sessions/{sid}").json()["camera"]
    p, t = np.array(cam["position"]), np.array(cam["target"])
    f = (t - p) / np.linalg.norm(t - p)
    right = np.cross(f, cam["up"])
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    half = np.tan(np.radians(cam["fov_y"]) / 2)
    for b in boxes:
        for corner in np.array(np.meshgrid(*b.T)).T.reshape(-1, 3):
            q = corner - p
            assert abs(q @ right / (q @ f)) <= half * PORTRAIT and abs(q @ up / (q @ f)) <= half
    # a material the query names is still used as named
    named = upload(api, sid, model, format="obj", size=4, material=0)
    assert named.status_code == 201 and api.get(f"/api/sessions/{sid}/scene").json()["meshes"][-1]["material"] == 0


def test_a_model_in_the_cornell_box_lands_inside_its_walls(api):
    r = api.post("/api/sessions", json={"mesh_scene": {"kind": "cornell", "detail": 0}, "settings": SMALL})
    sid = r.json()["id"]
    added = upload(api, sid, export_mesh(box((0, 0, 0), (1, 1, 1)), "obj"), format="obj", size=30)
    assert added.status_code == 201, added.text
    scene = api.get(f"/api/sessions/{sid}/scene").json()
    boxes = object_boxes_of(scene)
    new = boxes[-1]
    assert np.all(new[0] >= -20.0) and np.all(new[1] <= 20.0), new  # inside the box's walls, not behind one
    assert not any(boxes_overlap(new, b) for b in boxes[:-1])

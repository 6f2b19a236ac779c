"""Meshes through the API (issue #20): scenes with meshes in and out, model files uploaded as
bytes, bad meshes refused with 422 naming the field (413 for bodies too large), frames
served by the methods that trace triangles on the GPU (every one-pass method and auto) and
refused with 422 by those that do not (the ray engines, naming ``method``)."""

from __future__ import annotations

import base64
import io
import json
import math
import time
import warnings

import numpy as np
import pytest

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from pocketray_server_support import SMALL, make_config

from renderer.mesh_io import export_mesh
from renderer.meshes import box, icosphere
from renderer.scene import Scene
from server.app import create_app

pytestmark = pytest.mark.gl  # the app's lifespan starts the GL worker
MAX_TRIANGLES = 3000  # POCKETRAY_MAX_TRIANGLES of this module's app
MAX_BODY = 256 * 1024


@pytest.fixture(scope="module")
def api(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("meshes")
    with TestClient(create_app(make_config(tmp, max_triangles=MAX_TRIANGLES, max_body_bytes=MAX_BODY))) as c:
        yield c


def mesh_scene_json(**mesh) -> dict:
    ball = icosphere(1, radius=5.0).to_json()
    cube = {
        "vertices": box((-1, -1, -1), (1, 1, 1)).vertices.tolist(),
        "triangles": box((-1, -1, -1), (1, 1, 1)).triangles.tolist(),
        "material": 1,
        "transform": [[2, 0, 0, 10], [0, 2, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]],
    }
    cube.update(mesh)
    return {
        "materials": [{}, {"color": [0.2, 0.5, 0.9]}],
        "spheres": [{"center": [-12, 0, 0], "radius": 2}],
        "planes": [{"point": [0, -20, 0], "normal": [0, 1, 0]}],
        "meshes": [ball, cube],
    }


def create(api, scene: dict, **settings):
    return api.post("/api/sessions", json={"scene": scene, "settings": {**SMALL, **settings}})


def assert_422(r, field: str) -> None:
    assert r.status_code == 422, r.text
    msgs = [d["msg"] for d in r.json()["detail"]]
    assert any(field in m for m in msgs), f"{field!r} not named in {msgs}"


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


def test_device_data_of_a_scene_with_meshes_holds_the_triangles(api):
    sid = create(api, mesh_scene_json()).json()["id"]
    r = api.get(f"/api/sessions/{sid}/device-data")
    assert r.status_code == 200, r.text
    from server.frames.device_data import decode_blob

    header, textures = decode_blob(r.content)
    assert "TRIANGLES" in header["shader"]["features"] and "u_triangles" in textures
    assert header["uniforms"]["u_tri_base"] == 2


def test_a_method_without_meshes_on_gpu_is_refused_with_422_meshes(api, monkeypatch):
    """The per-method refusal (Capabilities.meshes_on_gpu), for a method whose layout would
    hold spheres only — none does today, so bvh pretends: frames, renders and device data
    of a mesh scene are 422 'meshes' naming the methods that trace meshes."""
    import dataclasses

    from renderer.methods import METHODS

    monkeypatch.setattr(
        METHODS["bvh"], "capabilities", dataclasses.replace(METHODS["bvh"].capabilities, meshes_on_gpu=False)
    )
    sid = create(api, mesh_scene_json(), method="bvh").json()["id"]
    r = api.get(f"/api/sessions/{sid}/frame")
    assert_422(r, "meshes")
    assert "'bvh'" in r.text and "bih, bruteforce" in r.text
    assert_422(api.get(f"/api/sessions/{sid}/device-data"), "meshes")
    assert_422(
        api.post("/api/render", json={"scene": mesh_scene_json(), "settings": {**SMALL, "method": "bvh"}}), "meshes"
    )


def test_the_ray_engines_refuse_a_scene_with_meshes_naming_the_method(api):
    r = create(api, mesh_scene_json(), method="rayengine")
    assert_422(r, "method")
    assert "spheres and planes only" in r.text
    sid = create(api, mesh_scene_json()).json()["id"]
    assert_422(api.patch(f"/api/sessions/{sid}/settings", json={"method": "hre"}), "method")


def raw(text: str) -> dict:
    return {"content": text.encode(), "headers": {"content-type": "application/json"}}


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
    assert_422(create(api, mesh_scene_json(**change)), field)


def test_a_nan_vertex_is_refused_naming_it(api):
    text = json.dumps({"scene": mesh_scene_json(), "settings": SMALL})
    bad = text.replace("[-1.0, -1.0, -1.0]", "[-1.0, NaN, -1.0]", 1)
    assert bad != text
    assert_422(api.post("/api/sessions", **raw(bad)), "scene.meshes[1].vertices[0][1]")


def test_too_many_triangles_422_over_the_cap_and_413_over_the_body_limit(api):
    many = icosphere(4)  # 5,120 triangles > POCKETRAY_MAX_TRIANGLES = 3,000 of this app
    body = mesh_scene_json()
    body["meshes"] = [{"vertices": np.round(many.vertices, 3).tolist(), "triangles": many.triangles.tolist()}]
    assert len(json.dumps(body)) < MAX_BODY
    r = create(api, body)
    assert_422(r, "scene.meshes")
    assert "POCKETRAY_MAX_TRIANGLES" in r.text
    huge = icosphere(5)
    body["meshes"] = [{"vertices": huge.vertices.tolist(), "triangles": huge.triangles.tolist()}]
    assert create(api, body).status_code == 413


def upload(api, sid: str, data: bytes, **query):
    return api.post(
        f"/api/sessions/{sid}/meshes", params=query, content=data, headers={"content-type": "application/octet-stream"}
    )


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
    assert api.get(f"/api/sessions/{sid}").json()["camera"] == camera


def test_bad_uploads_are_refused_and_change_nothing(api):
    sid = create(api, mesh_scene_json()).json()["id"]
    before = api.get(f"/api/sessions/{sid}").json()
    assert_422(upload(api, sid, b"this is not a mesh", format="ply"), "body")
    assert_422(upload(api, sid, b"", format="obj"), "body")
    assert_422(upload(api, sid, export_mesh(box(), "obj"), format="dae"), "format")
    assert_422(upload(api, sid, export_mesh(box(), "obj"), format="obj", material=9), "material")
    over = upload(api, sid, export_mesh(icosphere(4), "stl"), format="stl")  # 5,120 triangles
    assert_422(over, "body")
    assert "POCKETRAY_MAX_TRIANGLES" in over.text
    assert upload(api, sid, b"\0" * (MAX_BODY + 1), format="stl").status_code == 413
    assert api.get(f"/api/sessions/{sid}").json() == before
    assert upload(api, "nosuchsession", export_mesh(box(), "obj"), format="obj").status_code == 404


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
    assert_422(
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
    assert_422(create(api, body), "motions")
    body["motions"] = [{"kind": "incoherent", "mesh": 0}]
    assert_422(create(api, body), "scene.motions[0].mesh")


def test_info_states_the_triangle_cap_and_what_each_method_traces(api):
    info = api.get("/api/info").json()
    assert info["limits"]["max_triangles"] == MAX_TRIANGLES
    assert info["method_settings"]["rayengine"]["primitives"] == ["spheres", "planes"]
    assert "triangles" in info["method_settings"]["bih"]["primitives"]
    assert {m for m, x in info["method_settings"].items() if x["meshes_on_gpu"]} == {
        "bih",
        "bruteforce",
        "bvh",
        "kdtree",
        "twolevel",
        "auto",
    }
    assert math.isfinite(api.get("/api/info").json()["limits"]["max_frame_cost"])


def test_a_mesh_scene_recipe_makes_a_session_of_its_triangles(api):
    from renderer.scenarios import mesh_scene

    r = api.post("/api/sessions", json={"mesh_scene": {"kind": "mixed", "detail": 1}, "settings": SMALL})
    assert r.status_code == 201, r.text
    info = r.json()["scene_info"]
    want = mesh_scene("mixed", 1)
    assert info["mesh_scene"] == {"kind": "mixed", "detail": 1, "smooth": True}
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


def vm_hwm_kib() -> int:
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
    raise AssertionError("no VmHWM")


def test_hostile_model_files_get_a_quick_422_naming_the_problem(api):
    """A 250-byte glTF whose accessor claims 30,000,000 vertices (before: 2.3 GB of peak memory
    and 7.5 s, in the service's own process, then 422), a node tree deeper than the limit, a
    binary STL whose header count disagrees with its length (before: ModuleNotFoundError where
    charset-normalizer was not installed), a PLY short of its declared faces and an OBJ face
    of index 0 (both accepted before): each refused with 422 saying what is wrong."""
    octets = {"content-type": "application/octet-stream"}
    assert (
        api.post("/api/meshes", params={"format": "obj"}, content=export_mesh(box(), "obj"), headers=octets).status_code
        == 200
    )  # the parser processes have started
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
        assert time.perf_counter() - t0 < 3.0
        assert_422(r, "body")
        assert "accessors[0].count = 30,000,000; at most 3,145,728 allowed" in r.text
    assert vm_hwm_kib() - hwm < 100 * 1024  # KiB: no array of 30 M vertices here

    stl = export_mesh(icosphere(1), "stl")
    r = upload(api, sid, stl[:80] + (81).to_bytes(4, "little") + stl[84:], format="stl")
    assert_422(r, "body")
    assert "header says 81 triangles, which take 84 + 50 × 81 = 4,134 bytes; the file has 4,084" in r.text
    ply = (
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        b"element face 1000\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    )
    assert "element face 1,000 (1,003 rows); the file holds 4" in upload(api, sid, ply, format="ply").text
    r = upload(api, sid, b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", format="obj")
    assert_422(r, "body")
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
    assert_422(r, "body")
    assert "MAX_MODEL_NODE_DEPTH" in r.text
    assert api.get(f"/api/sessions/{sid}").json()["scene_info"]["n_meshes"] == 2  # nothing was added
